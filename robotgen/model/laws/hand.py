"""Settings of the hand-space laws of a 6-joint chain (Lee and Lee 1983): resolved
acceleration control (Luh, Walker and Paul 1980) and resolved motion adaptive control.

Both run once per sampling period T on the measured joint state and a desired hand
trajectory (pose, twist [v; omega] and its derivative, base coordinates), and output joint
torques. The hand is the chain's tip frame, or a tool frame fixed in it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotgen.model.parameters import RuntimeParameter

HAND_DOF = 6  # the laws resolve hand motion through a square Jacobian
HAND_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
STATE_NAMES = ("px", "py", "pz", "roll", "pitch", "yaw", "vx", "vy", "vz", "wx", "wy", "wz")  # eq 20


@dataclass(frozen=True, eq=False)
class ResolvedAccelerationSettings:
    """xdd* = xdd_d + Kv (xd_d - xd) + Kp e, qdd = J^-1 (xdd* - Jdot qd), tau by Newton-Euler.

    kp, kv: (6,) per hand axis (x, y, z, then rotation about x, y, z), diagonal gains."""

    period: float
    tool: np.ndarray  # (4, 4) tip frame -> hand frame
    kp: np.ndarray
    kv: np.ndarray
    runtime: bool = True  # kp, kv read at run time

    def parameters(self, node: str) -> list[RuntimeParameter]:
        if not self.runtime:
            return []
        axes = ", ".join(HAND_AXES)
        return [RuntimeParameter(f"{node}_kp", (HAND_DOF,), tuple(map(float, self.kp)),
                                 f"hand position gains Kp of '{node}' on {axes}"),
                RuntimeParameter(f"{node}_kv", (HAND_DOF,), tuple(map(float, self.kv)),
                                 f"hand velocity gains Kv of '{node}' on {axes}")]


@dataclass(frozen=True, eq=False)
class AdaptiveSettings:
    """Resolved motion adaptive control: Newton-Euler feedforward along the resolved desired
    trajectory, and feedback on the hand-state perturbation dx (eq 20) by the one-step optimal
    control (eq 39) of a model dx(k+1) = A dx(k) + B du(k) (eq 29) identified by recursive
    least squares with forgetting (eq 37), started from the linearised dynamics (eqs 24-32).

    q:  (12,) diagonal of Q (eq 38) on (p, Phi, v, Omega); r: (6,) diagonal of R.
    forgetting: r of eq 37, 0 < r <= 1. initial_covariance: P_0 = p0 I.
    covariance_limit: trace(P) is held below it (with r < 1 an unexcited P grows).
    ik_iterations: Newton steps of the inverse kinematics per cycle, from the prediction of
    the previous cycle's resolved joint trajectory."""

    period: float
    tool: np.ndarray
    q: np.ndarray
    r: np.ndarray
    forgetting: float
    initial_covariance: float
    covariance_limit: float
    ik_iterations: int
    runtime: bool = True  # q, r, forgetting read at run time

    def parameters(self, node: str) -> list[RuntimeParameter]:
        if not self.runtime:
            return []
        return [RuntimeParameter(f"{node}_q", (12,), tuple(map(float, self.q)),
                                 f"state weights Q (eq 38) of '{node}' on {', '.join(STATE_NAMES)}"),
                RuntimeParameter(f"{node}_r", (HAND_DOF,), tuple(map(float, self.r)),
                                 f"torque weights R (eq 38) of '{node}'"),
                RuntimeParameter(f"{node}_forgetting", (), (float(self.forgetting),),
                                 f"forgetting factor r (eq 37) of '{node}', 0 < r <= 1")]
