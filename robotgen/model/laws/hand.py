"""Settings of the hand-space laws of a 6-joint chain (Lee and Lee 1983): resolved
acceleration control (Luh, Walker and Paul 1980) and resolved motion adaptive control.

Both run once per sampling period T on the measured joint state and a desired hand
trajectory (pose, twist [v; omega] and its derivative, base coordinates), and output joint
torques. The hand is the chain's tip frame, or a tool frame fixed in it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotgen.model.parameters import Bounds, RuntimeParameter

HAND_DOF = 6  # the laws resolve hand motion through a square Jacobian
HAND_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
STATE_NAMES = ("px", "py", "pz", "roll", "pitch", "yaw", "vx", "vy", "vz", "wx", "wy", "wz")  # eq 20

# The values the laws' settings may take: the spec's (robotgen.frontend.control.hand) and, for
# those read at run time, a value given to the emitted module (robotgen.model.parameters).
GAIN = Bounds.positive("gain")  # Kp, Kv per hand axis
WEIGHT = Bounds.positive("weight")  # an entry of Q's or R's diagonal (eq 38)
Q_MATRIX, R_MATRIX = Bounds.definite("Q", "eq 38"), Bounds.definite("R", "eq 38")
TORQUE_WEIGHT = Bounds.positive("torque weight")  # kappa of the rule R = kappa B0^T Q B0
FORGETTING = Bounds("forgetting factor", minimum=0.0, exclusive=True, maximum=1.0, note="eq 37")


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
        """Run-time parameters of a resolved acceleration node: hand gains Kp and Kv (6,)."""
        if not self.runtime:
            return []
        axes = ", ".join(HAND_AXES)
        return [
            RuntimeParameter(
                f"{node}_kp",
                (HAND_DOF,),
                tuple(map(float, self.kp)),
                f"hand position gains Kp of '{node}' on {axes}",
                GAIN,
            ),
            RuntimeParameter(
                f"{node}_kv",
                (HAND_DOF,),
                tuple(map(float, self.kv)),
                f"hand velocity gains Kv of '{node}' on {axes}",
                GAIN,
            ),
        ]


# The first step after a controller's reset refuses a desired hand pose farther than this from
# the hand (robotgen.symbolic.root_laws.hand.start_check): a path started in the wrong frame or
# at the wrong place. The adaptive law closes a start error within a few periods, so its first
# torques grow with it: on the PUMA at its start pose (specs/puma560_rmac.yaml) about 76 N m per
# mm and 31 N m per mrad (1566 N m for 2 cm). Start the path at the hand: hand_pose(q).
START_DISTANCE = 0.01  # m, between the origins
START_ANGLE = 0.05  # rad, the rotation between the orientations


# Lee and Lee's regressor phi = (dx, du, 1): the blocks of the RLS covariance P_0 (eq 37)
COVARIANCE_BLOCKS = ("A", "B", "c")


@dataclass(frozen=True, eq=False)
class AdaptiveSettings:
    """Resolved motion adaptive control: Newton-Euler feedforward along the resolved desired
    trajectory, and feedback on the hand-state perturbation dx (eq 20) by the one-step optimal
    control (eqs 38-39) of a model dx(k+1) = A dx(k) + B du(k) + c (eq 29 with an affine term)
    identified by recursive least squares (eq 37), started from the linearised dynamics (eqs
    24-32).

    q: Q of eq 38 on (p, Phi, v, Omega), (12,) its diagonal or (12, 12) symmetric positive
       definite. By the weight rule (docs/spec-format.md) it comes from ``bandwidth``: the
       position and orientation rows weigh 2 bandwidth / period, the rates 1, so that the
       one-step control makes positions and orientations decay at ``bandwidth`` [rad/s].
    r: R of eq 38, (6,) its diagonal or (6, 6), or None for the rule R = torque_weight B0^T Q B0
       (B0 the model's B at the reset): the control then removes 1 / (1 + torque_weight) of
       the predicted rate error per period there, whatever the arm.
    forgetting: mu of eq 37's forgetting, 0 < mu <= 1.
    directional: forget along the regressor only (directional forgetting); False is eq 37 as
       printed (all of P divided by mu), which winds P up in closed loop.
    initial_covariance: P_0 on the regressor blocks (A's, B's, c's).
    covariance_limit: trace(P) is held below it, unless the forgetting is directional and the
       model affine (the regressor's constant 1 then keeps P bounded:
       robotgen.symbolic.root_laws.resolved_adaptive.identify).
    affine: the model's constant term c, identified and cancelled (the torque that holds a
       payload the model does not know).
    ik_iterations: Newton steps of the inverse kinematics per cycle (arms without a closed form)."""

    period: float
    tool: np.ndarray
    q: np.ndarray
    r: np.ndarray | None
    torque_weight: float
    bandwidth: float | None  # the rule's, None when q was given
    forgetting: float
    initial_covariance: tuple[float, float, float]  # COVARIANCE_BLOCKS
    covariance_limit: float
    ik_iterations: int
    affine: bool = True
    directional: bool = True
    runtime: bool = True  # q, r or torque_weight, forgetting read at run time

    @property
    def trace_limit(self) -> float | None:
        """The bound on the covariance's trace, or None when directional forgetting on an affine model needs none."""
        return None if self.affine and self.directional else self.covariance_limit

    @property
    def n_phi(self) -> int:
        """Parameters per output of the RLS model: 12 states, 6 inputs and the constant term."""
        return 12 + HAND_DOF + (1 if self.affine else 0)

    def parameters(self, node: str) -> list[RuntimeParameter]:
        """Run-time parameters of a resolved adaptive node: weights Q, R, the torque weight and forgetting."""
        if not self.runtime:
            return []
        out = [
            RuntimeParameter(
                f"{node}_q",
                self.q.shape,
                tuple(map(float, self.q.ravel())),
                f"state weights Q (eq 38) of '{node}' on {', '.join(STATE_NAMES)}"
                + (" (its diagonal)" if self.q.ndim == 1 else " (row-major, symmetric)"),
                WEIGHT if self.q.ndim == 1 else Q_MATRIX,
            )
        ]
        if self.r is None:
            out.append(
                RuntimeParameter(
                    f"{node}_torque_weight",
                    (),
                    (float(self.torque_weight),),
                    f"R = torque_weight B0^T Q B0 (eq 38) of '{node}', > 0",
                    TORQUE_WEIGHT,
                )
            )
        else:
            out.append(
                RuntimeParameter(
                    f"{node}_r",
                    self.r.shape,
                    tuple(map(float, self.r.ravel())),
                    f"torque weights R (eq 38) of '{node}'"
                    + (" (its diagonal)" if self.r.ndim == 1 else " (row-major, symmetric)"),
                    WEIGHT if self.r.ndim == 1 else R_MATRIX,
                )
            )
        out.append(
            RuntimeParameter(
                f"{node}_forgetting",
                (),
                (float(self.forgetting),),
                f"forgetting factor mu (eq 37) of '{node}', 0 < mu <= 1",
                FORGETTING,
            )
        )
        return out
