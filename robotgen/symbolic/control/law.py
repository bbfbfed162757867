"""What a control law needs from the robot it controls and what it gives back (Deno et al.
1990, §3.4): the interfaces every module of robotgen.symbolic.control implements. Adding a
law is one module with a ``LAW`` object and one line in robotgen.symbolic.control.tree_laws
(a TreeLaw) or root_laws (a RootLaw), plus its name in robotgen.model.laws.

A root law is the root of its spec and makes the module's functions itself: its kernels and
a report (info() keys and module attributes).

A law sees the controlled robot's graphs (its M, C, N, positions x and velocity v in its
own coordinates) and the trajectory written at the control node (desired positions if any
ATTACH above has h^-1, velocity, acceleration, force); it returns the force on the robot's
coordinates and the trajectory it passes down, and, if it integrates an expected trajectory
(x_e, xd_e), that trajectory's next value: the controller state the servo step carries in
and out (the emitted C keeps none of its own)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel
from robotgen.symbolic.node import NodeGraph
from robotgen.symbolic.rows import rows


class PositionsUnavailable(ValueError):
    """A controller needs desired positions, but an ATTACH above it has no h^-1."""


@dataclass(frozen=True, eq=False)
class Command:
    """What a law reads in one servo step, in the controlled robot's coordinates (its
    velocity coordinates: external, then the internal motions it exposes)."""

    robot: NodeGraph
    v_d: ca.SX  # desired velocity (zero on internal motions this controller resolves)
    a_d: ca.SX  # desired acceleration
    F_d: ca.SX  # force written from above
    feedback: Callable[[ca.SX | None], ca.SX]  # e -> Kv e' + Kp e (+ kv_internal on internal motions)
    position_error: Callable[[], ca.SX]  # x_d - x; raises PositionsUnavailable without x_d
    x_d: ca.SX | None  # desired positions, None when no h^-1 above lets them through
    expected: tuple[ca.SX, ca.SX] | None  # (x_e, xd_e): the integrated trajectory, stateful laws
    dt: ca.SX  # the servo period, stateful laws


@dataclass(frozen=True, eq=False)
class Written:
    """What a law writes to its robot: the force and the trajectory passed down, and the
    expected trajectory's next value (stateful laws)."""

    F: ca.SX
    x: ca.SX | None
    v: ca.SX
    a: ca.SX
    next_expected: ca.SX | None = None


@dataclass(frozen=True)
class TreeLaw:
    """A CONTROL law that composes in a robot tree.

    name:        the spec's ``law``.
    stateful:    integrates an expected trajectory (x_e, xd_e) from xdd_e (§3.4).
    transparent: the control node shows the robot's own M, C, N to the node above (a
                 stiffness, §4.3); otherwise its attributes are zero (the controller
                 absorbs the robot's dynamics).
    write:       Command -> Written."""

    name: str
    stateful: bool
    transparent: bool
    write: Callable[[Command], Written]

    def attributes(self, robot: NodeGraph, n: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """M, C, N of the control node, n its velocity dimension."""
        if self.transparent:
            return robot.M, robot.C, robot.N
        return ca.SX.zeros(n, n), ca.SX.zeros(n, n), ca.SX.zeros(n, 1)


@dataclass(frozen=True)
class StateView:
    """A block of a controller's state that its class shows read-only (an estimate)."""

    name: str
    offset: int
    rows: int
    cols: int
    doc: str


@dataclass(frozen=True)
class StartCheck:
    """What the first step after a reset refuses: ``kernel`` (inputs q and pose_d, one output)
    gives one distance per entry of ``limits`` (in ``units``); when one is above its limit (or
    NaN) the step returns status 3 having written nothing, and the controller stays reset.
    ``hint`` says what to do instead, in the Python message."""

    kernel: str
    limits: tuple[float, ...]
    units: tuple[str, ...]
    hint: str


@dataclass(frozen=True)
class Controller:
    """A controller object around one step kernel: a Python class in the module and a state
    struct with step/reset functions in C.

    The step kernel's inputs are q, qd, pose_d, twist_d, accel_d, then ``state`` (if
    state_size), then one input per flag (a number: 1 true, 0 false), then the parameters;
    its outputs tau, then ``state_next`` (if state_size). ``init`` (a kernel of the first five
    inputs and the parameters, output ``state``) gives the state the first step after a
    reset starts from."""

    class_name: str
    step: str
    period: float
    state_size: int = 0
    init: str | None = None
    flags: tuple[str, ...] = ()  # boolean attributes, True after construction
    views: tuple[StateView, ...] = ()
    start: StartCheck | None = None  # checked on the first step after a reset


@dataclass(frozen=True)
class RootLaw:
    """A CONTROL law that is the root of its spec: kernels(system) are the module's
    functions, report(system) its extra info() keys and module attributes, and
    controller(system), if any, the controller class the module offers."""

    name: str
    kernels: Callable[[RobotSystem], list[Kernel]]
    report: Callable[[RobotSystem], tuple[dict, dict]]
    controller: Callable[[RobotSystem], Controller] | None = None


def integrate(c: Command, a_e: ca.SX) -> ca.SX:
    """The expected trajectory one servo period on, at constant acceleration a_e:
    x_e + dt xd_e + dt^2 / 2 a_e on the positions, xd_e + dt a_e on the velocity."""
    x_s, v_s = c.expected
    nx = x_s.shape[0]
    return ca.vertcat(x_s + c.dt * rows(v_s, 0, nx) + 0.5 * c.dt ** 2 * rows(a_e, 0, nx), v_s + c.dt * a_e)
