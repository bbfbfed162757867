"""A spec's `simulation` section: how `robotgen simulate` runs the closed loop."""

from __future__ import annotations

from dataclasses import dataclass, field

from robotgen.errors import Location
from robotgen.model.chain import KinematicTree

# the plant `robotgen simulate` closes the loop around: robotgen's own model (the default), an
# independent MuJoCo model of the same system (robotgen.simulation.mujoco), or both side by side
ROBOTGEN_PLANT, MUJOCO_PLANT, BOTH_PLANTS = "robotgen", "mujoco", "both"
PLANTS = (ROBOTGEN_PLANT, MUJOCO_PLANT, BOTH_PLANTS)


@dataclass(frozen=True)
class PayloadChange:
    """From time ``at`` on, the plant's hand holds ``mass`` (a point mass at ``com``, in the
    hand frame; 0 drops what it held), or in a robot tree the rigid_body ``payload`` has
    ``mass``; the controller is not told."""

    at: float
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    payload: str = ""  # a robot tree's rigid_body node ("" for a hand)


# A wall's spring and damper in robotgen's plant, unless the spec gives them: stiff enough that a
# 10 N push goes 0.1 mm in, and 300 N s/m damps a 1 kg point against it nearly critically
# (2 sqrt(1e5 * 1) = 632); sqrt(1e5 / 1) dt = 0.32 at dt = 1 ms, well inside RK4's reach
WALL_STIFFNESS = 1e5  # N/m
WALL_DAMPING = 300.0  # N s/m
# the largest constraint residual |y - h^-1(h(y))| accepted at a start pose [m or rad]: simulated
# from, or linearised at (robotgen info)
RESIDUAL_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Wall:
    """A flat, frictionless wall in the plant that the point of node ``node`` touches: ``node``'s
    coordinates are the point (a frame change's fingertip or tip, in metres), the wall fills
    the half-space (x - point) . normal < 0 and pushes the point out along ``normal`` (a unit
    vector) with stiffness * depth + damping * d(depth)/dt, never pulling (robotgen's plant,
    robotgen.simulation.wall_contact; MuJoCo's plant has its own soft contact)."""

    node: str
    point: tuple[float, ...]
    normal: tuple[float, ...]
    stiffness: float = WALL_STIFFNESS
    damping: float = WALL_DAMPING


@dataclass(frozen=True)
class SimulationSettings:
    """The spec's simulation section: duration and dt [s], start, the desired path's sine, forces, wall and payload
    changes."""

    duration: float = 2.0
    dt: float = 1e-3
    start: tuple[float, ...] | None = None  # root positions at t = 0 (needs inverse kinematics)
    theta0: tuple[float, ...] | None = None  # or the leaf joint positions at t = 0
    initial_error: tuple[float, ...] = ()  # the plant starts at start + initial_error
    amplitude: tuple[float, ...] = ()  # x_d(t) = start + amplitude sin(2 pi frequency t)
    frequency: tuple[float, ...] = ()
    internal_forces: tuple[float, ...] = ()  # root f_i, if the root leaves some unresolved
    force: tuple[float, ...] = ()  # root f_e: the force written at the root (zeros without it)
    payload_changes: tuple[PayloadChange, ...] = ()  # the plant's payload changes mid-run, in time order
    wall: Wall | None = None  # a wall in the plant
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
