"""Resolved motion adaptive control (Lee and Lee 1983), a root law on a 6-joint chain.

One sampling period k, from the measured joint state (q, qd) and the desired hand trajectory
(pose, twist [v; Omega], its derivative):

Feedforward (§4.1, Table 1's four stages)
  1. q_d by inverse kinematics (closed form for a spherical wrist, else Newton steps) from the
     previous period's resolved joint trajectory carried one period on;
  2. qd_d = J^-1 [v_d; Omega_d] (eq 11);
  3. qdd_d = J^-1 ([vdot_d; Omegadot_d] - Jdot qd_d) (eq 13);
  4. u_n by Newton-Euler at (q_d, qd_d, qdd_d).
Feedback (§4.2, Table 1's three stages)
  1. the hand state x = (p, Phi, v, Omega) (eqs 1, 2, 8, 20) and the nominal x_n from the
     desired trajectory; dx = x - x_n (angle differences wrapped);
  2. recursive least squares with forgetting r (eq 37) for the rows of [A B] of
     dx(k) = A dx(k-1) + B du(k-1) (eq 29), with one P for all rows (phi_k is shared): with
     g = P phi / (phi^T P phi + r), each row moves by the prediction error times g and
     P <- (P - P phi phi^T P / (phi^T P phi + r)) / r, formed symmetric, its trace held below
     a limit (without excitation and r < 1 it would grow without bound);
  3. du = -(R + B^T Q B)^-1 B^T Q A dx (eq 39), by an L D L^T solve.
  tau = u_n + du.

The identification starts from the linearised model: F = df/dx, L = df/du of the hand-space
state equations (eq 19) at the nominal, by AD (eqs 24-28), and A = exp(F T),
B = int exp(F s) ds L (eqs 29-32). That is the ``init`` kernel, run on the first period after
a reset; the controller's state (A, B, P, the last phi, the resolved joint trajectory) is the
caller's, passed in and out of each step."""
from __future__ import annotations

import casadi as ca

from robotgen.model.laws import RESOLVED_ADAPTIVE
from robotgen.model.laws.hand import AdaptiveSettings
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.system import RobotSystem
from robotgen.symbolic.control.hand import Hand, discretise, pose_rows, wrap
from robotgen.symbolic.control.law import Controller, RootLaw, StateView
from robotgen.symbolic.kernel import Kernel, ParameterSymbols, make_kernel
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rigid_body.rpy import rpy_of

NX, NU = 12, 6  # hand state and torques
NPHI = NX + NU
STEP, INIT = "adaptive_step", "adaptive_init"
# the controller's state, in this order
LAYOUT = (("A", NX, NX), ("B", NX, NU), ("P", NPHI, NPHI), ("phi", NPHI, 1), ("q_d", NU, 1), ("qd_d", NU, 1),
          ("qdd_d", NU, 1))
OFFSETS = {}
_o = 0
for _name, _r, _c in LAYOUT:
    OFFSETS[_name] = (_o, _r, _c)
    _o += _r * _c
STATE_SIZE = _o


def unpack(state: ca.SX) -> dict[str, ca.SX]:
    """The state's blocks, matrices row-major."""
    out = {}
    for name, (o, r, c) in OFFSETS.items():
        block = state[o:o + r * c]
        out[name] = ca.reshape(block, c, r).T if c > 1 else block
    return out


def pack(blocks: dict[str, ca.SX]) -> ca.SX:
    return ca.vertcat(*[ca.reshape(blocks[name].T, r * c, 1) for name, r, c in LAYOUT])


class Weights:
    """Q, R and r: run-time parameters or folded constants."""

    def __init__(self, name: str, s: AdaptiveSettings, parameters: ParameterSymbols):
        p = parameters.symbols
        self.q = p.get(f"{name}_q", ca.DM(s.q))
        self.r = p.get(f"{name}_r", ca.DM(s.r))
        self.forgetting = p.get(f"{name}_forgetting", s.forgetting)


class Inputs:
    def __init__(self):
        self.q, self.qd = ca.SX.sym("q", NU), ca.SX.sym("qd", NU)
        self.pose_d = ca.SX.sym("pose_d", 16)
        self.twist_d, self.accel_d = ca.SX.sym("twist_d", 6), ca.SX.sym("accel_d", 6)

    def ports(self) -> list[tuple]:
        return [("q", self.q), ("qd", self.qd), ("pose_d", self.pose_d, (4, 4)), ("twist_d", self.twist_d),
                ("accel_d", self.accel_d)]


def feedforward(hand: Hand, s: AdaptiveSettings, i: Inputs, q_start: ca.SX, iterations: int) -> dict[str, ca.SX]:
    """The four feedforward stages: q_d, qd_d, qdd_d and the nominal torques u_n."""
    R_d, p_d = pose_rows(i.pose_d)
    q_d = hand.inverse_kinematics(R_d, p_d, q_start, iterations)
    qd_d = hand.joint_rates(q_d, i.twist_d)
    qdd_d = hand.joint_accelerations(q_d, qd_d, i.accel_d)
    return {"q_d": q_d, "qd_d": qd_d, "qdd_d": qdd_d, "u_n": hand.torques(q_d, qd_d, qdd_d)}


def perturbation(hand: Hand, i: Inputs) -> ca.SX:
    """dx = x - x_n (eq 20), the roll, pitch, yaw differences wrapped to (-pi, pi]."""
    return _error(hand.state(i.q, i.qd), i)


def identify(A: ca.SX, B: ca.SX, P: ca.SX, phi: ca.SX, dx: ca.SX, r, limit: float,
             adapt: ca.SX | float = 1.0) -> tuple[ca.SX, ca.SX, ca.SX]:
    """One step of eq 37 for every row of [A B], with the shared P; ``adapt`` = 0 leaves
    A, B and P as they are (the gain g and the forgetting are switched off, not the
    arithmetic: no selection per entry)."""
    Theta = ca.horzcat(A, B)
    Pphi = P @ phi
    g = Pphi * (adapt / (ca.dot(phi, Pphi) + r))
    Theta = Theta + (dx - Theta @ phi) @ g.T
    # (P - P phi phi^T P / (phi^T P phi + r)) / r on the upper triangle, mirrored
    inv_r = ca.if_else(adapt, 1 / r, 1)
    P_next = ca.SX(NPHI, NPHI)
    for a in range(NPHI):
        for b in range(a, NPHI):
            P_next[a, b] = (P[a, b] - Pphi[a] * g[b]) * inv_r
            P_next[b, a] = P_next[a, b]
    trace = sum((P_next[k, k] for k in range(NPHI)), ca.SX(0))
    P_next = P_next * ca.fmin(1, limit / trace)
    return Theta[:, :NX], Theta[:, NX:], P_next


def one_step_control(A: ca.SX, B: ca.SX, dx: ca.SX, q, r) -> ca.SX:
    """du* = -(R + B^T Q B)^-1 B^T Q A dx (eq 39), Q and R diagonal."""
    QB = ca.diag(q) @ B
    H = ca.diag(r) + B.T @ QB
    return -cholesky_solve(H, QB.T @ (A @ dx))


def step_graph(system: RobotSystem) -> tuple[list[tuple], list[tuple], ParameterSymbols]:
    """The step kernel's inputs and outputs (make_kernel's form) and the parameters."""
    node = system.root_node
    s: AdaptiveSettings = node.hand
    parameters = ParameterSymbols.of(runtime_parameters(system))
    hand = Hand(system.nodes[node.robot].leaf, s.tool)
    w = Weights(node.name, s, parameters)
    T = s.period
    i = Inputs()
    state = ca.SX.sym("state", STATE_SIZE)
    adapt = ca.SX.sym("adapt")
    old = unpack(state)
    q_start = old["q_d"] + T * old["qd_d"] + 0.5 * T ** 2 * old["qdd_d"]
    ff = feedforward(hand, s, i, q_start, s.ik_iterations)
    dx = perturbation(hand, i)
    A, B, P = identify(old["A"], old["B"], old["P"], old["phi"], dx, w.forgetting, s.covariance_limit, adapt)
    du = one_step_control(A, B, dx, w.q, w.r)
    tau = ff["u_n"] + du
    new = {"A": A, "B": B, "P": P, "phi": ca.vertcat(dx, du), "q_d": ff["q_d"], "qd_d": ff["qd_d"],
           "qdd_d": ff["qdd_d"]}
    inputs = [*i.ports(), ("state", state), ("adapt", adapt)]
    outputs = [("tau", tau, (NU, 1)), ("dx", dx, (NX, 1)), ("state_next", pack(new), (STATE_SIZE, 1))]
    return inputs, outputs, parameters


def kernels(system: RobotSystem) -> list[Kernel]:
    node = system.root_node
    s: AdaptiveSettings = node.hand
    tree = system.nodes[node.robot].leaf
    hand = Hand(tree, s.tool)
    T = s.period
    inputs, outputs, parameters = step_graph(system)
    step = make_kernel(
        STEP, "Resolved motion adaptive control (Lee and Lee 1983), one sampling period: Newton-Euler "
        "feedforward along the resolved desired trajectory plus the one-step optimal feedback (eq 39) of "
        "the RLS-identified perturbation model (eq 37); adapt = 0 freezes the identification. The state "
        "(A, B, P, the last phi, the resolved joint trajectory) comes from adaptive_init or the previous "
        "step. Also the hand perturbation dx (eq 20).", inputs, outputs, parameters, guarded=True)

    # the first state after a reset: the linearised model at the nominal
    j = Inputs()
    ff0 = feedforward(hand, s, j, j.q, max(2 * s.ik_iterations, 4))
    F, L = hand.linearisation(ff0["q_d"], ff0["qd_d"], ff0["qdd_d"])
    A0, B0 = discretise(F, L, T)
    first = {"A": A0, "B": B0, "P": s.initial_covariance * ca.SX.eye(NPHI), "phi": ca.SX.zeros(NPHI),
             "q_d": ff0["q_d"], "qd_d": ff0["qd_d"], "qdd_d": ff0["qdd_d"]}
    init = make_kernel(
        INIT, "The adaptive controller's state for its first period: the resolved desired joint trajectory "
        "(inverse kinematics from the measured q) and the perturbation model linearised there (eqs 24-28) "
        "and discretised at T (eqs 29-32); P = p0 I.",
        j.ports(), [("state", pack(first), (STATE_SIZE, 1))], parameters, guarded=True)
    return leaf_kernels(tree, derivatives=system.derivatives.when_asked()) + [step, init]


# Lee and Lee 1983, Table 1: (multiplications, additions) per stage of one period
TABLE_1 = {
    "feedforward": {"inverse kinematics": (39, 32), "joint rates (eq 11)": (516, 242),
                    "joint accelerations (eq 13)": (108, 102), "Newton-Euler torques": (678, 597)},
    "feedback": {"hand state (eqs 1, 2, 8, 9)": (48 + 168, 22 + 138), "errors and identification (eq 37)": (1111, 1109),
                 "one-step optimal control (eq 39)": (2148, 1790)},
}


def stage_counts(system: RobotSystem) -> dict:
    """Operations of each of Table 1's stages, each stage's graph alone, and of the emitted
    step (the stages fused, common subexpressions shared)."""
    node = system.root_node
    s: AdaptiveSettings = node.hand
    hand = Hand(system.nodes[node.robot].leaf, s.tool)
    i = Inputs()
    sym = {name: ca.SX.sym(name, n) for name, n in (("q_start", NU), ("q_d", NU), ("qd_d", NU), ("qdd_d", NU),
                                                    ("x", NX), ("phi", NPHI), ("Q", NX), ("R", NU))}
    A, B, P = ca.SX.sym("A", NX, NX), ca.SX.sym("B", NX, NU), ca.SX.sym("P", NPHI, NPHI)
    R_d, p_d = pose_rows(i.pose_d)
    dx = ca.SX.sym("dx", NX)
    r = ca.SX.sym("r")
    stages = {
        "feedforward": {
            "inverse kinematics": ([i.pose_d, sym["q_start"]],
                                   [hand.inverse_kinematics(R_d, p_d, sym["q_start"], s.ik_iterations)]),
            "joint rates (eq 11)": ([sym["q_d"], i.twist_d], [hand.joint_rates(sym["q_d"], i.twist_d)]),
            "joint accelerations (eq 13)": ([sym["q_d"], sym["qd_d"], i.accel_d],
                                            [hand.joint_accelerations(sym["q_d"], sym["qd_d"], i.accel_d)]),
            "Newton-Euler torques": ([sym["q_d"], sym["qd_d"], sym["qdd_d"]],
                                     [hand.torques(sym["q_d"], sym["qd_d"], sym["qdd_d"])]),
        },
        "feedback": {
            "hand state (eqs 1, 2, 8, 9)": ([i.q, i.qd], [hand.state(i.q, i.qd)]),
            "errors and identification (eq 37)": (
                [sym["x"], i.pose_d, i.twist_d, A, B, P, sym["phi"], r],
                [*identify(A, B, P, sym["phi"], _error(sym["x"], i), r, s.covariance_limit)]),
            "one-step optimal control (eq 39)": ([A, B, dx, sym["Q"], sym["R"]],
                                                 [one_step_control(A, B, dx, sym["Q"], sym["R"])]),
        },
    }
    out: dict = {part: {name: count_operations(*graph) for name, graph in parts.items()}
                 for part, parts in stages.items()}
    for part in stages:
        out[part]["total"] = {k: sum(c[k] for c in out[part].values())
                              for k in ("mul", "add", "trig", "other", "total")}
    inputs, outputs, parameters = step_graph(system)
    out["step"] = count_operations([i[1] for i in inputs] + [parameters.vector], [o[1] for o in outputs])
    return out


def _error(x: ca.SX, i: Inputs) -> ca.SX:
    R_d, p_d = pose_rows(i.pose_d)
    dx = x - ca.vertcat(p_d, rpy_of(R_d), i.twist_d)
    return ca.vertcat(dx[:3], wrap(dx[3:6]), dx[6:])


def report(system: RobotSystem) -> tuple[dict, dict]:
    node = system.root_node
    s: AdaptiveSettings = node.hand
    info = {"controller": system.root, "robot": node.robot, "law": RESOLVED_ADAPTIVE, "period": s.period,
            "q": [float(v) for v in s.q], "r": [float(v) for v in s.r], "forgetting": s.forgetting,
            "initial_covariance": s.initial_covariance, "covariance_limit": s.covariance_limit,
            "ik_iterations": s.ik_iterations, "tool": [[float(v) for v in row] for row in s.tool],
            "state_layout": {name: {"offset": o, "shape": [r, c]} for name, (o, r, c) in OFFSETS.items()},
            "operation_counts": stage_counts(system),
            "table_1": {part: {name: {"mul": m, "add": a} for name, (m, a) in rows.items()}
                        for part, rows in TABLE_1.items()}}
    return {"hand_control": info}, {}


def controller(system: RobotSystem) -> Controller:
    views = tuple(StateView(name, *OFFSETS[name], doc) for name, doc in (
        ("A", "the identified A of dx(k+1) = A dx(k) + B du(k) (eq 29)"),
        ("B", "the identified B (eq 29)"), ("P", "the RLS covariance P (eq 37)")))
    return Controller("AdaptiveController", STEP, system.root_node.hand.period, STATE_SIZE, INIT, ("adapt",), views)


LAW = RootLaw(RESOLVED_ADAPTIVE, kernels, report, controller)
