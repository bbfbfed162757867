"""A spec's `simulation` section: how `robotgen simulate` runs the closed loop."""
from __future__ import annotations

from dataclasses import dataclass, field

from robotgen.errors import Location
from robotgen.model.chain import KinematicTree

# the plant `robotgen simulate` closes the loop around: robotgen's own model (the default), an
# independent MuJoCo model of the same system (robotgen.mujoco_plant), or both side by side
ROBOTGEN_PLANT, MUJOCO_PLANT, BOTH_PLANTS = "robotgen", "mujoco", "both"
PLANTS = (ROBOTGEN_PLANT, MUJOCO_PLANT, BOTH_PLANTS)


@dataclass(frozen=True)
class PayloadChange:
    """From time ``at`` on, the plant's hand holds ``mass`` (a point mass at ``com``, in the
    hand frame; 0 drops what it held); the controller is not told."""

    at: float
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SimulationSettings:
    duration: float = 2.0
    dt: float = 1e-3
    start: tuple[float, ...] | None = None  # root positions at t = 0 (needs inverse kinematics)
    theta0: tuple[float, ...] | None = None  # or the leaf joint positions at t = 0
    initial_error: tuple[float, ...] = ()  # the plant starts at start + initial_error
    amplitude: tuple[float, ...] = ()  # x_d(t) = start + amplitude sin(2 pi frequency t)
    frequency: tuple[float, ...] = ()
    internal_forces: tuple[float, ...] = ()  # root f_i, if the root leaves some unresolved
    payload_changes: tuple[PayloadChange, ...] = ()  # hand laws: the plant's payload changes mid-run, in time order
    plant: str = ROBOTGEN_PLANT  # one of PLANTS
    # where each field stands in the spec (for messages about values that only the running
    # simulation can judge, such as a theta0 that breaks a grasp)
    locations: dict[str, Location] = field(default_factory=dict, compare=False, repr=False)


def rest_posture(leaves) -> tuple[float, ...]:
    """Where a simulation starts when its spec says nothing: every chain joint at the middle
    of its position limits (0 without them), every other leaf coordinate at 0."""
    posture: list[float] = []
    for leaf in leaves:
        if isinstance(leaf, KinematicTree):
            for j in leaf.coordinate_joints:
                lo, hi = j.limits.lower, j.limits.upper
                posture.append(0.5 * (lo + hi) if lo is not None and hi is not None else 0.0)
        else:
            posture += [0.0] * leaf.nq
    return tuple(posture)
