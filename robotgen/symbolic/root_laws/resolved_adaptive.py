"""Resolved motion adaptive control (Lee and Lee 1983), a root law on a 6-joint chain.

One sampling period k, from the measured joint state (q, qd) and the desired hand trajectory
(pose, twist [v; Omega], its derivative):

Feedforward (§4.1, Table 1's four stages)
  1. q_d by inverse kinematics: closed form for an arm with a spherical wrist, else Newton
     steps from the previous period's resolved joint trajectory carried one period on;
  2. qd_d = J^-1 [v_d; Omega_d] (eq 11);
  3. qdd_d = J^-1 ([vdot_d; Omegadot_d] - Jdot qd_d) (eq 13);
  4. u_n by Newton-Euler at (q_d, qd_d, qdd_d).
Feedback (§4.2, Table 1's three stages)
  1. the hand state x = (p, Phi, v, Omega) (eqs 1, 2, 8, 20) and the nominal x_n from the
     desired trajectory; dx = x - x_n (angle differences wrapped);
  2. recursive least squares (eq 37) for the rows of Theta = [A B c] of
     dx(k) = A dx(k-1) + B du(k-1) + c (eq 29 and an affine term), with one P for all rows
     (phi = (dx, du, 1) is shared): with g = P phi / (phi^T P phi + mu), each row moves by its
     prediction error times g (eq 37's gain), and P <- P - eps P phi g^T,
     eps = 1 - (1 - mu) / (phi^T P phi): forgetting along phi only (directional forgetting,
     Kulhavy 1987), where eq 37 divides all of P by r. In closed loop du follows dx, the data
     excite only part of Theta, and eq 37's P/r grows without bound in the rest; the next
     disturbance then moves A and B far, and the torque jumps (docs/papers.md measures it);
  3. du = u_c - (R + B^T Q B)^-1 B^T Q A dx (eqs 38-39), where u_c = -(B^T Q B + delta R)^-1
     B^T Q c holds the model at rest at dx = 0 (eq 38 taken about the identified model's
     equilibrium, so that R does not weigh the torque that carries a payload; delta keeps it
     bounded where B tends to 0). The weight rule takes
     R = kappa B0^T Q B0, B0 the model's B at the reset: there the control removes
     1 / (1 + kappa) of the predicted rate error per period.
  tau = u_n + du.

The identification starts from the linearised model: F = df/dx, L = df/du of the hand-space
state equations (eq 19) at the nominal, by AD (eqs 24-28), A = exp(F T),
B = int exp(F s) ds L (eqs 29-32) and c = 0. That is the ``init`` kernel, run on the first
period after a reset; the controller's state (A, B, c, P, the last phi, the resolved joint
trajectory) is the caller's, passed in and out of each step."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from robotgen.model.laws import RESOLVED_ADAPTIVE
from robotgen.model.laws.hand import AdaptiveSettings
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.simulation import rest_posture
from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel, ParameterSymbols, make_kernel
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rigid_body.rpy import rpy_of
from robotgen.symbolic.root_laws.hand import (
    Hand,
    Linearisation,
    discretise,
    hand_kernels,
    pose_rows,
    start_check,
    wrap,
)
from robotgen.symbolic.root_laws.law import Controller, RootLaw, StateView

NX, NU = 12, 6  # hand state and torques
STEP, INIT = "adaptive_step", "adaptive_init"
TINY = 1e-30  # phi^T P phi is 0 only when phi is (the first period): no update then
HOLD_REGULARISATION = 1e-3  # delta of the holding torque u_c (one_step_control)
DISCRETISE_TERMS = 4  # of exp(F T)'s series (hand.discretise)


@dataclass(frozen=True)
class StateLayout:
    """The controller's state vector: its blocks in order, matrices row-major."""

    blocks: tuple[tuple[str, int, int], ...]

    @staticmethod
    def of(s: AdaptiveSettings) -> StateLayout:
        """The controller state's blocks for these settings: A, B, (c), P, phi, B0 and the previous desired joint
        state."""
        n = s.n_phi
        return StateLayout(
            (
                ("A", NX, NX),
                ("B", NX, NU),
                *((("c", NX, 1),) if s.affine else ()),
                ("P", n, n),
                ("phi", n, 1),
                ("B0", NX, NU),
                ("q_d", NU, 1),
                ("qd_d", NU, 1),
                ("qdd_d", NU, 1),
            )
        )

    @property
    def offsets(self) -> dict[str, tuple[int, int, int]]:
        """name -> (offset, rows, cols) of each block in the state vector."""
        out, o = {}, 0
        for name, r, c in self.blocks:
            out[name] = (o, r, c)
            o += r * c
        return out

    @property
    def size(self) -> int:
        """The state vector's length."""
        return sum(r * c for _, r, c in self.blocks)

    def unpack(self, state: ca.SX) -> dict[str, ca.SX]:
        """The blocks of a state vector, matrices row-major."""
        out = {}
        for name, (o, r, c) in self.offsets.items():
            block = state[o : o + r * c]
            out[name] = ca.reshape(block, c, r).T if c > 1 else block
        return out

    def pack(self, blocks: dict[str, ca.SX]) -> ca.SX:
        """The state vector of its blocks, matrices row-major."""
        return ca.vertcat(*[ca.reshape(blocks[name].T, r * c, 1) for name, r, c in self.blocks])


def _matrix(symbol: ca.SX | ca.DM, n: int) -> ca.SX:
    """A weight of eq 38 as read: its diagonal (n entries) or the matrix (n^2, row-major)."""
    symbol = ca.SX(symbol)
    return ca.diag(symbol) if symbol.numel() == n else ca.reshape(symbol, n, n).T


class Weights:
    """Q, R (or the rule's kappa) and mu: run-time parameters or folded constants."""

    def __init__(self, name: str, s: AdaptiveSettings, parameters: ParameterSymbols):
        p = parameters.symbols
        self.q_values = ca.SX(p.get(f"{name}_q", ca.DM(s.q.ravel())))  # Q's diagonal, or Q row-major
        self.Q = _matrix(self.q_values, NX)
        self.R = None if s.r is None else _matrix(p.get(f"{name}_r", ca.DM(s.r.ravel())), NU)
        self.kappa = p.get(f"{name}_torque_weight", ca.SX(s.torque_weight))
        self.forgetting = p.get(f"{name}_forgetting", ca.SX(s.forgetting))


class Inputs:
    """The step's input symbols: q, qd (6,), pose_d (16,: a (4, 4) row-major), twist_d and accel_d (6,)."""

    def __init__(self):
        self.q, self.qd = ca.SX.sym("q", NU), ca.SX.sym("qd", NU)
        self.pose_d = ca.SX.sym("pose_d", 16)
        self.twist_d, self.accel_d = ca.SX.sym("twist_d", 6), ca.SX.sym("accel_d", 6)

    def ports(self) -> list[tuple]:
        """The input ports as make_kernel takes them (name, symbol[, shape])."""
        return [
            ("q", self.q),
            ("qd", self.qd),
            ("pose_d", self.pose_d, (4, 4)),
            ("twist_d", self.twist_d),
            ("accel_d", self.accel_d),
        ]


def feedforward(hand: Hand, i: Inputs, q_start: ca.SX, iterations: int) -> dict[str, ca.SX]:
    """The four feedforward stages: q_d, qd_d, qdd_d and the nominal torques u_n."""
    R_d, p_d = pose_rows(i.pose_d)
    q_d = hand.inverse_kinematics(R_d, p_d, q_start, iterations)
    qd_d = hand.joint_rates(q_d, i.twist_d)
    qdd_d = hand.joint_accelerations(q_d, qd_d, i.accel_d)
    return {"q_d": q_d, "qd_d": qd_d, "qdd_d": qdd_d, "u_n": hand.torques(q_d, qd_d, qdd_d)}


def perturbation(hand: Hand, i: Inputs) -> ca.SX:
    """dx = x - x_n (eq 20), the roll, pitch, yaw differences wrapped to (-pi, pi]."""
    return _error(hand.state(i.q, i.qd), i)


def identify(
    Theta: ca.SX,
    P: ca.SX,
    phi: ca.SX,
    dx: ca.SX,
    mu,
    limit: float | None,
    adapt: ca.SX | float = 1.0,
    directional: bool = True,
) -> tuple[ca.SX, ca.SX]:
    """One step of eq 37 for every row of Theta = [A B (c)] with the shared P; ``adapt`` = 0
    leaves Theta and P as they are (the gain is switched off, not the arithmetic: no
    selection per entry).

    Directional forgetting forgets the information about phi^T theta by mu and adds the new
    sample: P - eps P phi g^T, eps = 1 - (1 - mu) / s, s = phi^T P phi. It changes P only
    along P phi and leaves phi^T P phi = s / (s + mu) < 1: P grows only where phi is small.
    With the affine term phi ends in a constant 1 and P stays bounded; without it ``limit``
    holds trace(P) (None: no limit). ``directional`` = False is eq 37 as printed:
    (P - P phi g^T) / mu."""
    n = phi.shape[0]
    Pphi = P @ phi
    g, eg, scale = rls_gain(Pphi, phi, adapt, mu, directional)
    Theta = ca.horzcat(*[parameter_row(Theta[k, :].T, phi, dx[k], g) for k in range(Theta.shape[0])]).T
    P_next = ca.SX(n, n)  # the upper triangle, mirrored
    for a in range(n):
        for b in range(a, n):
            P_next[a, b] = covariance_entry(P[a, b], Pphi[a], eg[b], scale)
            P_next[b, a] = P_next[a, b]
    if limit is None:
        return Theta, P_next
    return Theta, P_next * trace_factor(ca.diag(P_next), limit)


def rls_gain(p_phi: ca.SX, phi: ca.SX, adapt, mu, directional: bool) -> tuple[ca.SX, ca.SX, ca.SX | None]:
    """Eq 37's gain g = P phi adapt / (phi^T P phi + mu) from P phi; the gain P's update takes
    (eps g under directional forgetting, else g); and the factor on the updated P (1 / mu while
    adapting, as eq 37 prints it; None under directional forgetting)."""
    s = ca.dot(phi, p_phi)
    g = p_phi * (adapt / (s + mu))
    if directional:
        return g, g * (1 - (1 - mu) / ca.fmax(s, TINY)), None
    return g, g, ca.if_else(adapt, 1 / mu, 1)


def parameter_row(theta: ca.SX, phi: ca.SX, dx_k: ca.SX, g: ca.SX) -> ca.SX:
    """Row k of Theta after eq 37: theta_k + (dx_k - theta_k . phi) g (a column)."""
    return theta + (dx_k - ca.dot(theta, phi)) * g


def trace_factor(diagonal: ca.SX, limit: float) -> ca.SX:
    """What the updated P is multiplied by so that its trace stays at most ``limit``."""
    return ca.fmin(1, limit / ca.sum1(diagonal))


def covariance_entry(p: ca.SX, p_phi_a: ca.SX, eg_b: ca.SX, scale: ca.SX | None) -> ca.SX:
    """Entry (a, b) of the updated P: P_ab - (P phi)_a (eps g)_b, times the factor if any."""
    return p - p_phi_a * eg_b if scale is None else (p - p_phi_a * eg_b) * scale


def one_step_torque(H: ca.SX, R: ca.SX, feedback_term: ca.SX, hold_term: ca.SX | None) -> ca.SX:
    """du of eq 39 from H = B^T Q B, R, B^T Q A dx and B^T Q c (None: no affine term)."""
    du = -cholesky_solve(H + R, feedback_term)
    return du if hold_term is None else du - cholesky_solve(H + HOLD_REGULARISATION * R, hold_term)


def _gram(B: ca.SX, QB: ca.SX) -> ca.SX:
    """B^T Q B from B and Q B, each entry once (it is symmetric)."""
    n = B.shape[1]
    H = ca.SX(n, n)
    for a in range(n):
        for b in range(a, n):
            H[a, b] = ca.dot(B[:, a], QB[:, b])
            H[b, a] = H[a, b]
    return H


def torque_weight(Q: ca.SX, R: ca.SX | None, kappa, B0: ca.SX) -> ca.SX:
    """R of eq 38: given, or the rule's kappa B0^T Q B0 with B0 the model's B at the reset."""
    return _gram(B0, Q @ B0) * kappa if R is None else R


def one_step_control(A: ca.SX, B: ca.SX, c: ca.SX | None, dx: ca.SX, Q: ca.SX, R: ca.SX) -> ca.SX:
    """du = u_c - (R + B^T Q B)^-1 B^T Q A dx (eq 39), u_c = -(B^T Q B + delta R)^-1 B^T Q c the
    torque that holds the identified model at rest (x'^T Q x' least at dx = 0, regularised
    by delta = HOLD_REGULARISATION so that it stays bounded where B tends to 0, an arm held
    fast): du minimises x'^T Q x' + (du - u_c)^T R (du - u_c), x' = A dx + B du + c (eq 38
    about the model's equilibrium)."""
    QB = Q @ B
    return one_step_torque(_gram(B, QB), R, QB.T @ (A @ dx), None if c is None else QB.T @ c)


@dataclass
class _Step:
    """What both forms of the step start from: the settings, its input symbols (the measured
    and desired hand, the controller's state, adapt), the parameters and weights, and the
    values every period computes first: the feedforward along the resolved trajectory
    predicted from the state, and the perturbation dx."""

    s: AdaptiveSettings
    layout: StateLayout
    parameters: ParameterSymbols
    weights: Weights
    i: Inputs
    state: ca.SX
    adapt: ca.SX
    old: dict[str, ca.SX]
    ff: dict[str, ca.SX]
    dx: ca.SX

    @staticmethod
    def of(system: RobotSystem) -> _Step:
        node = system.root_control
        s = node.adaptive
        layout = StateLayout.of(s)
        parameters = ParameterSymbols.of(runtime_parameters(system))
        hand = Hand(system.tree(node.robot), s.tool)
        i, state = Inputs(), ca.SX.sym("state", layout.size)
        old = layout.unpack(state)
        q_start = old["q_d"] + s.period * old["qd_d"] + 0.5 * s.period**2 * old["qdd_d"]
        ff = feedforward(hand, i, q_start, s.ik_iterations)
        weights = Weights(node.name, s, parameters)
        return _Step(s, layout, parameters, weights, i, state, ca.SX.sym("adapt"), old, ff, perturbation(hand, i))

    @property
    def inputs(self) -> list[tuple]:
        """The step kernel's input ports (make_kernel's form)."""
        return [*self.i.ports(), ("state", self.state), ("adapt", self.adapt)]

    @property
    def shapes(self) -> list[tuple[str, tuple[int, int]]]:
        """Its outputs' names and shapes."""
        return [("tau", (NU, 1)), ("dx", (NX, 1)), ("state_next", (self.layout.size, 1))]


def step_graph(system: RobotSystem) -> tuple[list[tuple], list[tuple], ParameterSymbols]:
    """The step as one straight-line graph (the emitted step's loops compute the same:
    tests/control/test_adaptive_loops.py): its inputs and outputs (make_kernel's form) and the
    parameters."""
    st = _Step.of(system)
    s, w, old, dx = st.s, st.weights, st.old, st.dx
    Theta = ca.horzcat(old["A"], old["B"], *((old["c"],) if s.affine else ()))
    Theta, P = identify(Theta, old["P"], old["phi"], dx, w.forgetting, s.trace_limit, st.adapt, s.directional)
    A, B = Theta[:, :NX], Theta[:, NX : NX + NU]
    c = Theta[:, NX + NU] if s.affine else None
    du = one_step_control(A, B, c, dx, w.Q, torque_weight(w.Q, w.R, w.kappa, old["B0"]))
    new = {
        "A": A,
        "B": B,
        "P": P,
        "phi": ca.vertcat(dx, du, *((1,) if s.affine else ())),
        "B0": old["B0"],
        "q_d": st.ff["q_d"],
        "qd_d": st.ff["qd_d"],
        "qdd_d": st.ff["qdd_d"],
    }
    if c is not None:  # an affine model's c (the layout has its block then only)
        new["c"] = c
    values = [st.ff["u_n"] + du, dx, st.layout.pack(new)]
    return st.inputs, [(name, v, shape) for (name, shape), v in zip(st.shapes, values)], st.parameters


def _looped_step(st: _Step):
    """The step's identification and one-step control as loops (adaptive_loops), its
    feedforward and dx the prologue; the weights, run-time parameters or constants, read
    from local arrays."""
    from robotgen.symbolic.root_laws.adaptive_loops import step_schedule  # (it reads this module's constants)

    s, w = st.s, st.weights
    weights = {
        "q": w.q_values,
        "r": None if w.R is None else ca.vec(w.R.T),
        "kappa": ca.SX(w.kappa),
        "mu": ca.SX(w.forgetting),
        "limit": s.trace_limit,
        "directional": s.directional,
        "affine": s.affine,
    }
    prologue = {"u_n": st.ff["u_n"], "dx": st.dx, **{k: st.ff[k] for k in ("q_d", "qd_d", "qdd_d")}}
    sizes = [rows * cols for _, (rows, cols) in st.shapes]
    return step_schedule([port[1] for port in st.inputs], sizes, st.layout.offsets, prologue, weights)


def _reset_parts(hand: Hand, s: AdaptiveSettings, i: Inputs) -> tuple[dict[str, ca.SX], Linearisation, ca.DM]:
    """What the reset's state is made of: the feedforward from the measured q, the parts of the
    model linearised there (F, L: eqs 24-28) and P_0's diagonal."""
    ff = feedforward(hand, i, i.q, max(2 * s.ik_iterations, 4))
    parts = hand.linearisation_parts(ff["q_d"], ff["qd_d"], ff["qdd_d"])
    p_a, p_b, p_c = s.initial_covariance
    return ff, parts, ca.DM([p_a] * NX + [p_b] * NU + ([p_c] if s.affine else []))


def initial_state(hand: Hand, s: AdaptiveSettings, i: Inputs) -> ca.SX:
    """The state after a reset: the resolved desired joint trajectory (inverse kinematics from
    the measured q), the model linearised there and discretised (eqs 24-32), c = 0, P_0."""
    ff, parts, p0 = _reset_parts(hand, s, i)
    A0, B0 = discretise(parts.F, parts.L, s.period, DISCRETISE_TERMS)
    return StateLayout.of(s).pack(
        {
            "A": A0,
            "B": B0,
            "c": ca.SX.zeros(NX),
            "P": ca.SX(ca.diag(p0)),
            "phi": ca.SX.zeros(s.n_phi),
            "B0": B0,
            "q_d": ff["q_d"],
            "qd_d": ff["qd_d"],
            "qdd_d": ff["qdd_d"],
        }
    )


def _looped_init(hand: Hand, s: AdaptiveSettings, i: Inputs):
    """initial_state with F's acceleration rows and the discretisation as loops (adaptive_loops.init_schedule)."""
    from robotgen.symbolic.root_laws.adaptive_loops import init_schedule

    ff, parts, p0 = _reset_parts(hand, s, i)
    values = {**ff, "P0": p0}
    layout = StateLayout.of(s)
    return init_schedule(
        [p[1] for p in i.ports()], layout.size, layout.offsets, values, parts, s.period, DISCRETISE_TERMS
    )


def kernels(system: RobotSystem) -> list[Kernel]:
    """The resolved motion adaptive control kernels (Lee and Lee 1983) of the root's 6-joint chain."""
    node = system.root_control
    s = node.adaptive
    tree = system.tree(node.robot)
    hand = Hand(tree, s.tool)
    st = _Step.of(system)
    doc = (
        "Resolved motion adaptive control (Lee and Lee 1983), one sampling period: Newton-Euler "
        "feedforward along the resolved desired trajectory plus the one-step optimal feedback (eq 39) of "
        "the RLS-identified perturbation model (eq 37); adapt = 0 freezes the identification. The state "
        "(A, B, c, P, the last phi, the resolved joint trajectory) comes from adaptive_init or the previous "
        "step. Also the hand perturbation dx (eq 20)."
    )
    step = make_kernel(
        STEP,
        doc,
        st.inputs,
        [(name, None, shape) for name, shape in st.shapes],
        st.parameters,
        guarded=True,
        schedule=_looped_step(st),
    )
    j = Inputs()
    init = make_kernel(
        INIT,
        "The adaptive controller's state for its first period: the resolved desired joint trajectory "
        "(inverse kinematics from the measured q) and the perturbation model linearised there (eqs 24-28) "
        "and discretised at T (eqs 29-32); c = 0 and P = P_0.",
        j.ports(),
        [("state", None, (StateLayout.of(s).size, 1))],
        st.parameters,
        guarded=True,
        schedule=_looped_init(hand, s, j),
    )
    return leaf_kernels(tree, derivatives=system.derivatives.when_asked()) + hand_kernels(hand) + [step, init]


def _error(x: ca.SX, i: Inputs) -> ca.SX:
    R_d, p_d = pose_rows(i.pose_d)
    dx = x - ca.vertcat(p_d, rpy_of(R_d), i.twist_d)
    return ca.vertcat(dx[:3], wrap(dx[3:6]), dx[6:])


# Lee and Lee 1983, Table 1: (multiplications, additions) per stage of one period. The paper
# computes the feedforward and the feedback in parallel, and feedback stage 1's two parts in
# parallel, so its period costs max(feedforward, feedback) with stage 1 the larger part:
# 168 + 1111 + 2148 = 3427 multiplications, 138 + 12 + 1097 + 1790 = 3037 additions.
TABLE_1 = (
    ("feedforward", "1", "inverse kinematics", (39, 32)),
    ("feedforward", "2", "joint rates (eq 11)", (516, 242)),
    ("feedforward", "3", "joint accelerations (eq 13)", (108, 102)),
    ("feedforward", "4", "Newton-Euler torques", (678, 597)),
    ("feedback", "1a", "hand pose (eqs 1, 2)", (48, 22)),
    ("feedback", "1b", "hand velocity (eqs 8, 9)", (168, 138)),
    ("feedback", "2", "errors and identification (eq 37)", (0 + 1111, 12 + 1097)),
    ("feedback", "3", "one-step optimal control (eq 39)", (2148, 1790)),
)
KINDS = ("mul", "add", "trig", "other", "total")


def stage_counts(system: RobotSystem) -> dict:
    """Operations of each of Table 1's stages, given what the stages before it computed (stage
    3 of the feedforward is counted as what it adds to stage 2, whose J^-1 the paper's stage 3
    reuses), the totals in the paper's accounting (parallel parts counted by the larger), and
    the emitted step (its prologue and loops, robotgen.symbolic.root_laws.adaptive_loops)."""
    node = system.root_control
    s = node.adaptive
    hand = Hand(system.tree(node.robot), s.tool)
    parameters = ParameterSymbols.of(runtime_parameters(system))
    w = Weights(node.name, s, parameters)
    i = Inputs()
    sym = {
        name: ca.SX.sym(name, n)
        for name, n in (
            ("q_start", NU),
            ("q_d", NU),
            ("qd_d", NU),
            ("qdd_d", NU),
            ("x", NX),
            ("dx", NX),
            ("phi", s.n_phi),
        )
    }
    n_theta = NX + NU + (1 if s.affine else 0)
    Theta, P = ca.SX.sym("Theta", NX, n_theta), ca.SX.sym("P", s.n_phi, s.n_phi)
    B0 = ca.SX.sym("B0", NX, NU)
    R_d, p_d = pose_rows(i.pose_d)
    qd_d = hand.joint_rates(sym["q_d"], i.twist_d)
    qdd_d = hand.joint_accelerations(sym["q_d"], qd_d, i.accel_d)
    pose_R, pose_p = hand.pose(i.q)
    c = Theta[:, NX + NU] if s.affine else None
    graphs = {
        "inverse kinematics": (
            [i.pose_d, sym["q_start"]],
            [hand.inverse_kinematics(R_d, p_d, sym["q_start"], s.ik_iterations)],
        ),
        "joint rates (eq 11)": ([sym["q_d"], i.twist_d], [qd_d]),
        "joint accelerations (eq 13)": ([sym["q_d"], i.twist_d, i.accel_d], [qd_d, qdd_d]),
        "Newton-Euler torques": (
            [sym["q_d"], sym["qd_d"], sym["qdd_d"]],
            [hand.torques(sym["q_d"], sym["qd_d"], sym["qdd_d"])],
        ),
        "hand pose (eqs 1, 2)": ([i.q], [pose_p, rpy_of(pose_R)]),
        "hand velocity (eqs 8, 9)": ([i.q, i.qd], [hand.jacobian(i.q) @ i.qd]),
        "errors and identification (eq 37)": (
            [sym["x"], i.pose_d, i.twist_d, Theta, P, sym["phi"], parameters.vector],
            [*identify(Theta, P, sym["phi"], _error(sym["x"], i), w.forgetting, s.trace_limit, 1.0, s.directional)],
        ),
        "one-step optimal control (eq 39)": (
            [Theta, sym["dx"], B0, parameters.vector],
            [
                one_step_control(
                    Theta[:, :NX], Theta[:, NX : NX + NU], c, sym["dx"], w.Q, torque_weight(w.Q, w.R, w.kappa, B0)
                )
            ],
        ),
    }
    counts = {name: count_operations(*graph) for name, graph in graphs.items()}
    counts["joint accelerations (eq 13)"] = {
        k: counts["joint accelerations (eq 13)"][k] - counts["joint rates (eq 11)"][k] for k in KINDS
    }
    notes = {  # what robotgen computes in a row beyond the paper's quantity
        "inverse kinematics": "the branch nearest the prediction, each angle unwrapped to it, NaN out of reach, "
        "the singular wrist held"
        if hand.closed_form
        else f"{s.ik_iterations} Newton steps (no closed form for this arm)",
        "joint rates (eq 11)": "a singularity check (J^-1 [v; w] by two 3x3 solves at the wrist centre; the paper "
        "forms J^-1)"
        if hand.wrist_centre
        else "J and a Householder solve with its singularity check (the paper inverts J)",
        "joint accelerations (eq 13)": (
            "exact Jdot qd: the wrist centre's and the hand's accelerations at qdd = 0"
            if hand.wrist_centre
            else "exact Jdot qd by Newton-Euler's forward pass"
        )
        + " (the paper differences J over a period); counted as what it adds to stage 2",
        "errors and identification (eq 37)": f"{s.n_phi} regressors (the paper 18)",
    }
    rows: list[dict[str, Any]] = [
        {
            "part": part,
            "stage": stage,
            "name": name,
            "paper": {"mul": m, "add": a},
            "robotgen": counts[name],
            "note": notes.get(name, ""),
        }
        for part, stage, name, (m, a) in TABLE_1
    ]
    out: dict = {"rows": rows}

    def total(part: str, key: str) -> dict:
        chosen = [r for r in rows if r["part"] == part]
        if part == "feedback":  # stage 1's parts in parallel: the larger counts
            first = [r for r in chosen if r["stage"].startswith("1")]
            chosen = [max(first, key=lambda r: r[key]["mul"])] + [r for r in chosen if r not in first]
        kinds = KINDS if key == "robotgen" else ("mul", "add")
        return {k: sum(r[key][k] for r in chosen) for k in kinds}

    for key in ("paper", "robotgen"):
        parts = {part: total(part, key) for part in ("feedforward", "feedback")}
        out[key] = {
            **parts,
            "period": max(parts.values(), key=lambda t: t["mul"]),
            "sequential": {k: sum(r[key][k] for r in rows) for k in parts["feedback"]},
        }
    st = _Step.of(system)
    symbols = [port[1] for port in st.inputs] + ([st.parameters.vector] if st.parameters.parameters else [])
    executed = dict.fromkeys(KINDS, 0)  # what the emitted step executes
    for function, times in _looped_step(st).finish(symbols).executed():
        once = count_operations(function.sx_in(), function.call(function.sx_in()))
        for kind in KINDS:
            executed[kind] += times * once[kind]
    out["step"] = executed
    return out


def nominal_pose(system: RobotSystem) -> np.ndarray:
    """Where the weight rule's closed loop is evaluated: the simulation's theta0, else the
    middle of the joints' limits."""
    tree = system.tree(system.root_control.robot)
    sim = system.simulation
    if sim is not None and sim.theta0 is not None:
        return np.asarray(sim.theta0, float)
    return np.asarray(rest_posture([tree]), float)


def closed_loop(system: RobotSystem, q: np.ndarray | None = None) -> dict:
    """The one-step control's closed loop dx(k+1) = (A - B K) dx(k) on the model linearised
    at the joint pose q (default nominal_pose) with the hand at rest there, the spec's
    weights: its eigenvalues' moduli, the spectral radius and its margin to 1, and the
    slowest time constant -T / ln(radius)."""
    node = system.root_control
    s = node.adaptive
    hand = Hand(system.tree(node.robot), s.tool)
    q = nominal_pose(system) if q is None else np.asarray(q, float)
    i = Inputs()
    R, p = hand.pose(i.q)
    at_rest = [
        (i.pose_d, ca.reshape(ca.vertcat(ca.horzcat(R, p), ca.DM([[0, 0, 0, 1]])).T, 16, 1)),
        (i.twist_d, ca.SX.zeros(6)),
        (i.accel_d, ca.SX.zeros(6)),
        (i.qd, ca.SX.zeros(6)),
    ]
    state = ca.substitute([initial_state(hand, s, i)], [a for a, _ in at_rest], [b for _, b in at_rest])[0]
    blocks = StateLayout.of(s).unpack(ca.SX(ca.Function("state", [i.q], [state])(q)))
    A, B = (np.array(ca.DM(blocks[k]), float) for k in ("A", "B"))
    Q = np.diag(s.q) if s.q.ndim == 1 else s.q
    H = B.T @ Q @ B
    R_ = s.torque_weight * H if s.r is None else np.diag(s.r) if s.r.ndim == 1 else s.r
    K = np.linalg.solve(H + R_, B.T @ Q @ A)
    moduli = np.sort(np.abs(np.linalg.eigvals(A - B @ K)))[::-1]
    radius = float(moduli[0])
    return {
        "pose": [float(v) for v in q],
        "moduli": [float(f"{m:.4g}") for m in moduli],
        "spectral_radius": float(f"{radius:.6g}"),
        "margin": float(f"{1 - radius:.4g}"),
        "time_constant": float(f"{-s.period / np.log(radius):.4g}") if 0 < radius < 1 else float("inf"),
    }


def report(system: RobotSystem) -> tuple[dict, dict]:
    """(info entries, module attributes) of a resolved adaptive spec: its weights, forgetting and Table 1's counts."""
    node = system.root_control
    s = node.adaptive

    def listed(m: np.ndarray | None):
        return None if m is None else m.tolist()

    info = {
        "controller": system.root,
        "robot": node.robot,
        "law": RESOLVED_ADAPTIVE,
        "period": s.period,
        "q": listed(s.q),
        "r": listed(s.r),
        "torque_weight": s.torque_weight,
        "bandwidth": s.bandwidth,
        "forgetting": s.forgetting,
        "initial_covariance": dict(zip(("A", "B", "c"), s.initial_covariance)),
        "covariance_limit": s.covariance_limit,
        "affine": s.affine,
        "directional": s.directional,
        "ik_iterations": s.ik_iterations,
        "tool": [[float(v) for v in row] for row in s.tool],
        "state_layout": {name: {"offset": o, "shape": [r, c]} for name, (o, r, c) in StateLayout.of(s).offsets.items()},
        "operation_counts": stage_counts(system),
    }
    return {"hand_control": info}, {}


def controller(system: RobotSystem) -> Controller:
    """The module's AdaptiveController: step and init kernels, period [s], state size, and views of A, B, c, P."""
    s = system.root_control.adaptive
    layout = StateLayout.of(s)
    docs = {
        "A": "the identified A of dx(k+1) = A dx(k) + B du(k) + c (eq 29)",
        "B": "the identified B (eq 29)",
        "c": "the identified constant term c (the offset a payload makes)",
        "P": "the RLS covariance P (eq 37)",
    }
    views = tuple(StateView(name, *layout.offsets[name], doc) for name, doc in docs.items() if name in layout.offsets)
    return Controller("AdaptiveController", STEP, s.period, layout.size, INIT, ("adapt",), views, start_check())


LAW = RootLaw(RESOLVED_ADAPTIVE, kernels, report, controller)
