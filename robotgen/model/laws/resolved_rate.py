"""Resolved motion rate control (Whitney 1972) of a chain or a composite robot, as plain settings.

A `control` node with ``law: resolved_rate`` is a kinematic controller: it turns hand rates
commanded along six axes of a chosen coordinate system into joint rates (eqs 2-10), and a
target pose into hand rates by closed-loop re-planning (eqs 11-18), either with a fixed
horizon (an exponential approach) or with the time remaining until arrival (``Arrival``).
Optionally it carries an optimal regulator about a nominal posture, from the linearised
dynamics (eq 19).

The six command axes are ordered (v1 v2 v3 w1 w2 w3): three translation rates, then three
rotation rates, in the frame's coordinates. Each axis is either *active* (follows the
command, times its weight), *held* (rate zero: e.g. orientation held fixed while reaching)
or *free* (left out of the task; its rows leave the Jacobian, adding redundancy).

Over a composite robot (an ATTACH tree, Deno et al. 1990) the command coordinates are the
robot node's own (its rd) and the joint rates come from the tree's velocity map; only
damping, rate limits, the horizon and the arrival apply (``CompositeRateSettings``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

# command frames
BASE = "base"
HAND = "hand"
TOOL = "tool"
LINE_OF_SIGHT = "line_of_sight"
SPHERICAL = "spherical"
FRAMES = (BASE, HAND, TOOL, LINE_OF_SIGHT, SPHERICAL)

GENERIC_AXES = ("x", "y", "z", "rx", "ry", "rz")
# Whitney's hand axes (Fig. 1, eqs 7 and 11): sweep, reach, lift along hand x, y, z;
# tilt, twist, turn about them (twist is about the reach axis, 7Y).
AXIS_NAMES = {
    BASE: GENERIC_AXES,
    HAND: ("sweep", "reach", "lift", "tilt", "twist", "turn"),
    TOOL: ("sweep", "reach", "lift", "tilt", "twist", "turn"),
    LINE_OF_SIGHT: ("sweep", "sight", "lift", "tilt", "twist", "turn"),
    SPHERICAL: ("radius", "azimuth", "elevation", "tilt", "twist", "turn"),
}

# redundancy resolution
PSEUDO_INVERSE = "pseudo_inverse"
WEIGHTED_PSEUDO_INVERSE = "weighted_pseudo_inverse"
EXTENDED_JACOBIAN = "extended_jacobian"
JOINT_LIMITS = "joint_limits"
MANIPULABILITY = "manipulability"
REDUNDANCY_METHODS = (PSEUDO_INVERSE, WEIGHTED_PSEUDO_INVERSE, EXTENDED_JACOBIAN)
OBJECTIVES = ("none", JOINT_LIMITS, MANIPULABILITY)


@dataclass(frozen=True, eq=False)
class CommandFrame:
    """Where the command axes live.

    base:          base axes; v of the hand origin and omega (eq 8 without C7^T).
    hand:          hand axes (eq 7, C7^T applied).
    tool:          axes of a held tool, ``tool`` (4x4) fixed in the hand frame; its origin is
                   the controlled point.
    line_of_sight: the reach row replaced by motion along the unit vector from ``point`` (the
                   eye) to the hand (eq 10); sweep and lift are the hand's x and z axes made
                   perpendicular to that line; rotations in hand axes.
    spherical:     radius, azimuth, elevation of the hand origin about ``point`` (base z is
                   the polar axis); rotations in hand axes.
    """

    kind: str
    point: np.ndarray | None = None  # (3,) eye or centre, base coordinates
    tool: np.ndarray | None = None  # (4, 4), tool frame only

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The command frame's axis names."""
        return AXIS_NAMES[self.kind]

    @property
    def tool_pose(self) -> np.ndarray:
        """The held tool's (4, 4) pose in the hand frame (frame tool; a TypeError for another frame)."""
        if self.tool is None:
            raise TypeError(f"a {self.kind} command frame holds no tool")
        return self.tool

    @property
    def centre(self) -> np.ndarray:
        """The (3,) eye or centre in base coordinates [m] (frames line_of_sight and spherical; a
        TypeError for another frame)."""
        if self.point is None:
            raise TypeError(f"a {self.kind} command frame has no point")
        return self.point


@dataclass(frozen=True)
class Redundancy:
    """How joint rates are chosen when the task has fewer rows than the arm has joints.

    pseudo_inverse:          qdot = J+ Sdot + (I - J+ J) gain grad H  (Liegeois 1977).
    weighted_pseudo_inverse: qdot = J#W Sdot + (I - J#W J) W^-1 gain grad H with
                             J#W = W^-1 J^T (J W^-1 J^T)^-1, W = diag(joint_weights): the rate
                             of least qdot^T W qdot that meets J qdot = Sdot (Whitney 1969).
    extended_jacobian:       J augmented by d/dq (z^T grad H) = -gain z^T grad H, z spanning
                             null(J) (Baillieul 1985); one degree of redundancy only."""

    method: str = PSEUDO_INVERSE
    objective: str | None = None  # joint_limits | manipulability | None
    gain: float = 1.0
    joint_weights: tuple[float, ...] | None = None  # (n,) diagonal of W, weighted_pseudo_inverse only

    def summary(self) -> dict:
        """The settings as info() reports them."""
        out: dict[str, Any] = {"method": self.method, "objective": self.objective, "gain": self.gain}
        if self.joint_weights is not None:
            out["joint_weights"] = list(self.joint_weights)
        return out


@dataclass(frozen=True)
class Arrival:
    """Position control with the remaining time of eq 11: the caller passes the time left
    until the hand is to arrive, and the hand rates are the remaining displacement and
    rotation over it. Below ``minimum_remaining`` that time is taken as the minimum, so
    nothing divides by zero: at one control period the last call carries the hand onto the
    target, and afterwards it is held there as an exponential approach with that time
    constant."""

    minimum_remaining: float = 0.001

    def summary(self) -> dict:
        """The settings as info() reports them."""
        return {"minimum_remaining": self.minimum_remaining}


@dataclass(frozen=True)
class Damping:
    """Damped least squares: lambda^2 = lambda_max^2 (1 - w / threshold)^2 while the
    manipulability w is below ``threshold`` (Nakamura & Hanafusa 1986), zero above."""

    lambda_max: float
    threshold: float


@dataclass(frozen=True, eq=False)
class LQRSettings:
    """An optimal regulator about a nominal posture (eq 19, state (dtheta, dtheta_dot));
    with ``servo`` also the optimal linear servo on the same gains, its feedforward passed in
    (robotgen.numeric.linear_servo)."""

    nominal: np.ndarray  # (n,) joint positions; nominal rates zero
    q_weights: np.ndarray  # (2n,) state weights, diagonal of Q
    r_weights: np.ndarray  # (n,) input weights, diagonal of R
    servo: bool = False


@dataclass(frozen=True, eq=False)
class RateControlSettings:
    """Settings of a resolved-rate node (Whitney 1972): frame, axes followed, redundancy, damping, limits, horizon,
    lqr."""

    frame: CommandFrame
    active: tuple[bool, ...]  # (6,) follows the command
    free: tuple[bool, ...]  # (6,) left out of the task
    weights: np.ndarray  # (6,) proportion of each active axis
    redundancy: Redundancy
    damping: Damping | None
    rate_limits: np.ndarray | None  # (n,) |qdot_i| bounds, the whole vector is scaled
    horizon: float  # T of eqs 11 and 18: closed-loop time constant of position control
    lqr: LQRSettings | None = None
    arrival: Arrival | None = None  # arrival_step: T of eq 11 the remaining time

    @property
    def task_rows(self) -> tuple[int, ...]:
        """Indices of the command axes that are in the task (not free)."""
        return tuple(i for i in range(6) if not self.free[i])

    def summary(self) -> dict:
        """Plain data for info() and the manifest."""
        names = self.frame.axis_names
        out: dict[str, Any] = {
            "frame": self.frame.kind,
            "axes": list(names),
            "active": [n for n, a, f in zip(names, self.active, self.free) if a and not f],
            "held": [n for n, a, f in zip(names, self.active, self.free) if not a and not f],
            "free": [n for n, f in zip(names, self.free) if f],
            "weights": [float(w) for w in self.weights],
            "redundancy": self.redundancy.summary(),
            "damping": None
            if self.damping is None
            else {"lambda_max": self.damping.lambda_max, "threshold": self.damping.threshold},
            "rate_limits": None if self.rate_limits is None else [float(v) for v in self.rate_limits],
            "horizon": self.horizon,
        }
        if self.arrival is not None:
            out["arrival"] = self.arrival.summary()
        if self.frame.point is not None:
            out["eye" if self.frame.kind == LINE_OF_SIGHT else "centre"] = [float(v) for v in self.frame.point]
        if self.frame.tool is not None:
            out["tool"] = [[float(v) for v in row] for row in self.frame.tool]
        return out


# the settings a resolved_rate controller of a composite robot takes (the others are a chain's)
COMPOSITE_KEYS = ("damping", "rate_limits", "horizon", "arrival")


@dataclass(frozen=True, eq=False)
class CompositeRateSettings:
    """Resolved rate control of a composite robot R (an ATTACH node, possibly under control
    nodes). The command is a velocity of R in R's coordinates (R's rd: the external rates,
    then the internal-motion rates R exposes, a null-space command); the leaves' joint rates
    are the tree's velocity map A(theta) (every ATTACH's A composed down to the leaves)
    applied to it. A target position is reached through rates (x_target - x) / horizon,
    with the internal-motion rates zero (or over the remaining time, ``arrival``); ``angles``
    marks the external coordinates whose error is wrapped to (-pi, pi] (a rigid payload's
    psi, or roll, pitch, yaw)."""

    robot_names: tuple[str, ...]  # R's velocity coordinates, the command's entries
    n_external: int
    angles: tuple[bool, ...]  # (n_external,)
    damping: Damping | None
    rate_limits: np.ndarray | None  # (nq,) over the sensed leaf coordinates
    horizon: float
    arrival: Arrival | None = None

    def summary(self) -> dict:
        """Plain data for info() and the manifest."""
        external = self.robot_names[: self.n_external]
        out = {
            "frame": "node",
            "command": list(self.robot_names),
            "target": list(external),
            "internal_motions": list(self.robot_names[self.n_external :]),
            "wrapped": [n for n, a in zip(external, self.angles) if a],
            "damping": None
            if self.damping is None
            else {"lambda_max": self.damping.lambda_max, "threshold": self.damping.threshold},
            "rate_limits": None if self.rate_limits is None else [float(v) for v in self.rate_limits],
            "horizon": self.horizon,
        }
        if self.arrival is not None:
            out["arrival"] = self.arrival.summary()
        return out
