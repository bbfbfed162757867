"""Kernels of a resolved motion rate controller over one chain (Whitney 1972).

The module of a spec whose root is ``control: {law: resolved_rate, robot: <chain>}`` has the
chain's usual functions (fk, jacobian, ..., forward_dynamics) and:

- ``command_jacobian(q)``: the 6 x n Jacobian in the command coordinates (eqs 3, 7-10).
- ``rate_step(q, command) -> (qd, manipulability, condition)``: joint rates for six command
  rates (eq 4; held axes rate zero, free axes out of the task), damped near singularities,
  a null-space objective on redundant arms, scaled to the rate limits.
- ``position_step(q, target) -> (qd, error, manipulability, condition)``: closed-loop
  position control through rates (eqs 11-18), re-planned from the current q at every call:
  hand rates (b17(theta_f) - b17(theta)) / T and Omega alpha / T, resolved as above, with T
  the fixed horizon: an exponential approach.
- ``arrival_step(q, target, remaining) -> (qd, error, rate_scale, manipulability,
  condition)``: the same with T of eq 11 the time remaining until arrival, as Whitney's
  closed-loop variant takes "a new T" at every re-planning: the hand moves on the straight
  line at constant speed and turns about a fixed axis at a constant rate, and arrives when
  ``remaining`` reaches zero; rate_scale < 1 when the rate limits slowed it (it is late).
  Only when the spec has ``arrival``.
- ``objective(q)``: the secondary objective H, when the spec names one.
- ``lqr_step(q, qd) -> tau``: tau0 - K (q - q0, qd), the optimal regulator on the
  linearised dynamics about the nominal (eq 19), when the spec asks for one.
- ``servo_step(q, qd, v) -> tau``: lqr_step's torque plus v, the optimal linear servo's
  feedforward (robotgen.numeric.linear_servo), when ``lqr`` has ``servo: true``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from robotgen.model.chain import Joint, KinematicTree
from robotgen.model.laws.resolved_rate import (
    EXTENDED_JACOBIAN,
    JOINT_LIMITS,
    MANIPULABILITY,
    WEIGHTED_PSEUDO_INVERSE,
    LQRSettings,
    RateControlSettings,
)
from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel, make_kernel
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.rigid_body.axis_angle import rotation_vector
from robotgen.symbolic.root_laws.resolved_rate.command_frames import command_jacobian, hand, twist_map
from robotgen.symbolic.root_laws.resolved_rate.regulator import regulator
from robotgen.symbolic.root_laws.resolved_rate.resolution import (
    DampedResolver,
    conditioning,
    damping_squared,
    limited,
    null_vector,
    scale_to_limits,
)


def chain_and_settings(system: RobotSystem) -> tuple[KinematicTree, RateControlSettings]:
    """The root's chain and its resolved-rate settings."""
    node = system.root_control
    return system.tree(node.robot), node.chain_rate


class RateLaw:
    """Whitney's rate and position control of ``tree`` as SX expressions of q."""

    def __init__(self, tree: KinematicTree, settings: RateControlSettings):
        self.tree, self.s = tree, settings
        n = self.n = tree.nq
        self.q = ca.SX.sym("q", n)
        self.hand = hand(tree, settings.frame, self.q)
        self.M = twist_map(settings.frame, self.hand)
        self.J6 = command_jacobian(settings.frame, self.hand)
        rows = list(settings.task_rows)
        self.rows = rows
        self.J = self.J6[rows, :]
        self.m = len(rows)
        cond = conditioning(self.J)
        self.manipulability, self.condition = cond.manipulability, cond.condition
        d = settings.damping
        lam2 = damping_squared(self.manipulability, d.lambda_max, d.threshold) if d is not None else None
        r = settings.redundancy
        self.H, grad = self._objective()
        if r.method == EXTENDED_JACOBIAN:
            # Baillieul: the optimality condition g = z^T grad H = 0 as one more task row,
            # driven to zero at rate gain: d g / dq qdot = -gain g.
            if grad is None:  # the front end gives the extended Jacobian an objective
                raise TypeError("the extended Jacobian needs an objective")
            g = ca.dot(null_vector(self.J), grad)
            self._resolver = DampedResolver(ca.vertcat(self.J, ca.jacobian(g, self.q)), lam2)
            self._extra: ca.SX | None = -r.gain * g
            self._null: ca.SX | None = None
        elif r.method == WEIGHTED_PSEUDO_INVERSE:
            # qdot = J#W Sdot + (I - J#W J) W^-1 gain grad H, J#W = W^-1 J^T (J W^-1 J^T)^-1
            # (resolution.py); W^-1 grad H is the ascent of H per unit of qdot^T W qdot.
            w = np.asarray(r.joint_weights, dtype=float)
            self._resolver = DampedResolver(self.J, lam2, column_scale=1 / np.sqrt(w))
            self._extra = None
            self._null = (
                self._resolver.project_null(ca.DM(1 / w) * (r.gain * grad))
                if grad is not None and self.n > self.m
                else None
            )
        else:
            self._resolver = DampedResolver(self.J, lam2)
            self._extra = None
            self._null = self._resolver.project_null(r.gain * grad) if grad is not None and self.n > self.m else None

    def _objective(self) -> tuple[ca.SX | None, ca.SX | None]:
        """H(q) and its gradient: joint-limit distance (Liegeois 1977) or manipulability."""
        objective = self.s.redundancy.objective
        q = self.q
        if objective == JOINT_LIMITS:
            terms, grad = [], []
            limited = [j for j in self.tree.joints if _joint_range(j)]
            for i, j in enumerate(self.tree.joints):
                if (bounds := _joint_range(j)) is not None:
                    lower, upper = bounds
                    mid, half = 0.5 * (upper + lower), 0.5 * (upper - lower)
                    terms.append(((q[i] - mid) / half) ** 2)
                    grad.append(-(q[i] - mid) / (len(limited) * half**2))
                else:
                    grad.append(ca.SX(0))
            return -sum(terms, ca.SX(0)) / (2 * len(limited)), ca.vertcat(*grad)
        if objective == MANIPULABILITY:
            det = ca.det(self.J @ self.J.T)
            w = ca.sqrt(ca.fmax(det, 0))
            return w, ca.gradient(det, q) / (2 * ca.fmax(w, 1e-12))
        return None, None

    def unlimited(self, S: ca.SX) -> ca.SX:
        """Joint rates for task rates S (m,), before the rate limits."""
        if self._extra is not None:
            return self._resolver.pinv_times(ca.vertcat(S, self._extra))
        qd = self._resolver.pinv_times(S)
        return qd if self._null is None else qd + self._null

    def resolve(self, S: ca.SX) -> ca.SX:
        """Joint rates for task rates S (m,), limited."""
        return scale_to_limits(self.unlimited(S), self.s.rate_limits)

    def rate_step(self, command: ca.SX) -> ca.SX:
        """Joint rates (n,) resolving a (6,) hand-rate command on the active axes, weighted."""
        gate = np.array([w if a else 0.0 for w, a in zip(self.s.weights, self.s.active)])
        S6 = ca.SX(ca.DM(gate)) * command
        return self.resolve(S6[self.rows])

    def hand_rates(self, target: ca.SX, T: float | ca.SX) -> tuple[ca.SX, ca.SX]:
        """Task rates that carry the hand to ``target`` (16 entries, the 4x4 goal pose of the
        controlled frame, row-major) in time T, and the error (dp; Omega alpha)."""
        R_f = ca.vertcat(*[ca.horzcat(*[target[4 * i + k] for k in range(3)]) for i in range(3)])
        p_f = ca.vertcat(*[target[4 * i + 3] for i in range(3)])
        dp = p_f - self.hand.p  # b17(theta_f) - b17(theta), base coordinates (eq 11)
        rotation = rotation_vector(self.hand.R.T @ R_f)  # C_if (eq 14) -> Omega alpha (eqs 15-18)
        twist = ca.vertcat(dp / T, self.hand.R @ rotation / T)
        S6 = self.M @ twist  # hand frame: C7^T dp / T (eq 11) and Omega alpha / T
        return S6[self.rows], ca.vertcat(dp, rotation)

    def position_step(self, target: ca.SX) -> tuple[ca.SX, ca.SX]:
        """T the fixed horizon: re-planned at every call, an exponential approach."""
        S, error = self.hand_rates(target, self.s.horizon)
        return self.resolve(S), error

    def arrival_step(self, target: ca.SX, remaining: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """T of eq 11 the remaining time, at least the minimum: (qd, error, rate_scale).
        Re-planned with the new T at every call, the rate along the remaining displacement
        is |dp| / T, and |dp| shrinks as T does: a straight line at constant speed (the
        rotation about a fixed axis at a constant rate), arriving at T = 0."""
        if self.s.arrival is None:
            raise TypeError("arrival_step needs the settings' arrival")
        T = ca.fmax(remaining, self.s.arrival.minimum_remaining)
        S, error = self.hand_rates(target, T)
        qd, scale = limited(self.unlimited(S), self.s.rate_limits)
        return qd, error, scale


def _joint_range(joint: Joint) -> tuple[float, float] | None:
    """(lower, upper) of a joint with a range of positions, else None."""
    lim = joint.limits
    if lim.lower is not None and lim.upper is not None and lim.upper > lim.lower:
        return lim.lower, lim.upper
    return None


def chain_kernels(system: RobotSystem) -> list[Kernel]:
    """The resolved-rate kernels of a chain: rate, position and arrival steps, conditioning, lqr when set."""
    tree, s = chain_and_settings(system)
    law = RateLaw(tree, s)
    n, q = law.n, law.q
    names = ", ".join(s.frame.axis_names)
    command = ca.SX.sym("command", 6)
    target = ca.SX.sym("target", 16)
    qd_rate = law.rate_step(command)
    qd_pos, error = law.position_step(target)
    kernels = leaf_kernels(tree, derivatives=system.derivatives.when_asked()) + [
        make_kernel(
            "command_jacobian",
            f"Command rates per unit joint rate (Whitney 1972, eqs 3, 7-10), frame {s.frame.kind}: rows {names}.",
            [("q", q, (n, 1))],
            [("command_jacobian", law.J6, (6, n))],
        ),
        make_kernel(
            "rate_step",
            f"Resolved motion rate control (eq 4): joint rates for the command rates "
            f"({names}) in frame {s.frame.kind}; held axes rate zero, free axes out of the task; "
            "damped near singularities, scaled to the rate limits. Also the manipulability "
            "sqrt(det(J J^T)) and the condition number of the task Jacobian.",
            [("q", q, (n, 1)), ("command", command, (6, 1))],
            [
                ("qd", qd_rate, (n, 1)),
                ("manipulability", law.manipulability, (1, 1)),
                ("condition", law.condition, (1, 1)),
            ],
            guarded=True,
        ),
        make_kernel(
            "position_step",
            f"Position control through rates (eqs 11-18), re-planned from q at every "
            f"call: the hand rates that reach the target pose (4x4, base frame) in T = {s.horizon:g} s, "
            "resolved as rate_step does. error = (target - hand position in base coordinates, "
            "rotation vector Omega alpha of C_if in hand coordinates).",
            [("q", q, (n, 1)), ("target", target, (4, 4))],
            [
                ("qd", qd_pos, (n, 1)),
                ("error", error, (6, 1)),
                ("manipulability", law.manipulability, (1, 1)),
                ("condition", law.condition, (1, 1)),
            ],
            guarded=True,
        ),
    ]
    if s.arrival is not None:
        remaining = ca.SX.sym("remaining")
        qd_arr, error_arr, scale = law.arrival_step(target, remaining)
        kernels.append(
            make_kernel(
                "arrival_step",
                "Position control through rates with the remaining time (eq 11 with a new T at "
                "every call): the hand rates that reach the target pose (4x4, base frame) in the time remaining, "
                f"max(remaining, {s.arrival.minimum_remaining:g} s), resolved as rate_step does: a straight "
                "line at constant speed, a fixed rotation axis at a constant rate. error as position_step's; "
                "rate_scale = 1 / max(1, max_i |qd_i| / limit_i), below 1 when the rate limits slowed the hand "
                "(it arrives late).",
                [("q", q, (n, 1)), ("target", target, (4, 4)), ("remaining", remaining)],
                [
                    ("qd", qd_arr, (n, 1)),
                    ("error", error_arr, (6, 1)),
                    ("rate_scale", scale, (1, 1)),
                    ("manipulability", law.manipulability, (1, 1)),
                    ("condition", law.condition, (1, 1)),
                ],
                guarded=True,
            )
        )
    if law.H is not None:
        kernels.append(
            make_kernel(
                "objective",
                f"The secondary objective H(q) ({s.redundancy.objective}) that the redundancy resolution increases.",
                [("q", q, (n, 1))],
                [("objective", law.H, (1, 1))],
            )
        )
    if s.lqr is not None:
        kernels.extend(_lqr_kernels(tree, s.lqr))
    return kernels


def _lqr_kernels(tree: KinematicTree, lqr: LQRSettings) -> list[Kernel]:
    design = regulator(tree, lqr)
    n = tree.nq
    q, qd = ca.SX.sym("q", n), ca.SX.sym("qd", n)
    state = ca.vertcat(q - ca.DM(design.model.nominal), qd)
    tau = ca.DM(design.model.tau0) - ca.DM(design.K) @ state
    kernels = [
        make_kernel(
            "lqr_step",
            "Optimal regulator about the nominal posture (Whitney 1972, eq 19): "
            "tau = tau0 - K (q - q0, qd), K from the continuous Riccati equation of the "
            "linearised dynamics (module attribute lqr).",
            [("q", q, (n, 1)), ("qd", qd, (n, 1))],
            [("tau", tau, (n, 1))],
            guarded=True,
        )
    ]
    if lqr.servo:
        # the optimal linear servo u = -K s + v (robotgen.numeric.linear_servo, S1) on eq 19
        # applied to the whole state: the same K, v = R^-1 B^T g(t) computed offline
        v = ca.SX.sym("v", n)
        kernels.append(
            make_kernel(
                "servo_step",
                "Optimal linear servo (Whitney 1972, eq 19 applied to the "
                "whole state): tau = tau0 - K (q - q0, qd) + v, K as lqr_step, v = R^-1 B^T "
                "g(t) the feedforward of the reference, from "
                "robotgen.numeric.linear_servo.",
                [("q", q, (n, 1)), ("qd", qd, (n, 1)), ("v", v, (n, 1))],
                [("tau", tau + v, (n, 1))],
                guarded=True,
            )
        )
    return kernels


def chain_report(system: RobotSystem) -> tuple[dict, dict]:
    """(extra info() keys, module attributes) of a rate-controlled system."""
    tree, s = chain_and_settings(system)
    info = {"controller": system.root, "robot": system.root_control.robot, **s.summary()}
    attributes = {}
    if s.lqr is not None:
        design = regulator(tree, s.lqr)
        info["lqr"] = design.report
        attributes["lqr"] = {
            "K": design.K.tolist(),
            "A": design.model.A.tolist(),
            "B": design.model.B.tolist(),
            "nominal": design.model.nominal.tolist(),
            "tau0": design.model.tau0.tolist(),
            "Q": np.diag(design.Q).tolist(),
            "R": np.diag(design.R).tolist(),
            **design.report,
        }
    return {"rate_control": info}, attributes
