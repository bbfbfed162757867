"""What a tree control law needs from the robot it controls and what it gives back (Deno et al.
1990, §3.4): the interface every module of robotgen.symbolic.control implements. Adding a
law is one module with a ``LAW`` object and one line in robotgen.model.laws.registry
(docs/ARCHITECTURE.md, "Adding a law"); root laws are robotgen.symbolic.root_laws.

A law sees the controlled robot's graphs (its M, C, N, positions x and velocity v in its
own coordinates), the trajectory written at the control node (desired positions if any
ATTACH above has h^-1, velocity, acceleration, force) and, if it asks, the robot's rd force
term (what the robot exerts on what it touches, eqs 3.7, 5.4-5.5, sensed a period late); it
returns the force on the robot's coordinates and the trajectory it passes down, and, if it
keeps state (an expected trajectory (x_e, xd_e) it integrates, a force integral), that
state's next value: the controller state the servo step carries in and out (the emitted C
keeps none of its own)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from robotgen.model.system import ControlNode
from robotgen.symbolic.kernel import ParameterSymbols
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
    state: ca.SX | None  # the law's own block of the controller state, stateful laws
    dt: ca.SX  # the servo period, stateful laws
    node: ControlNode  # the control node, for the law's own settings
    parameters: ParameterSymbols  # the module's run-time parameters (the law's gains among them)
    sensed: Callable[[], tuple[ca.SX, ca.SX]]  # rd's force term (F_s, F_i,s) of the robot; laws that read forces

    @property
    def law_state(self) -> ca.SX:
        """The law's own block of the controller state (a stateful law's; a TypeError for another)."""
        if self.state is None:
            raise TypeError(f"law {self.node.law} of '{self.node.name}' keeps no state")
        return self.state

    @property
    def expected(self) -> tuple[ca.SX, ca.SX]:
        """(x_e, xd_e): the expected trajectory a computed-torque or feedforward law integrates."""
        nx = self.robot.sig.n_external
        return rows(self.law_state, 0, nx), rows(self.law_state, nx)


@dataclass(frozen=True, eq=False)
class Written:
    """What a law writes to its robot: the force and the trajectory passed down, and its
    state's next value (stateful laws)."""

    F: ca.SX
    x: ca.SX | None
    v: ca.SX
    a: ca.SX
    next_state: ca.SX | None = None


def reads_no_forces(node: ControlNode) -> bool:
    """The reads_forces of a law that never reads a sensed force."""
    return False


@dataclass(frozen=True)
class TreeLaw:
    """A CONTROL law that composes in a robot tree.

    name:         the spec's ``law``.
    transparent:  the control node shows the robot's own M, C, N to the node above (a
                  stiffness, §4.3); otherwise its attributes are zero (the controller
                  absorbs the robot's dynamics).
    write:        Command -> Written.
    state:        the law's state after a reset (servo_init), from the controlled robot's
                  graphs: an expected trajectory (x_e, xd_e) integrated from xdd_e starts at
                  (x, v) (§3.4), an integral at zero; None: the law keeps no state.
    reads_forces: whether the law at this node reads its robot's sensed forces (the servo
                  step then takes tau_sensed)."""

    name: str
    transparent: bool
    write: Callable[[Command], Written]
    state: Callable[[NodeGraph], ca.SX] | None = None
    reads_forces: Callable[[ControlNode], bool] = reads_no_forces

    @property
    def stateful(self) -> bool:
        """Whether the law carries a state from one servo step to the next."""
        return self.state is not None

    def attributes(self, robot: NodeGraph, n: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """M, C, N of the control node, n its velocity dimension."""
        if self.transparent:
            return robot.M, robot.C, robot.N
        return ca.SX.zeros(n, n), ca.SX.zeros(n, n), ca.SX.zeros(n, 1)


def expected_start(robot: NodeGraph) -> ca.SX:
    """An expected trajectory starts at the robot's current state."""
    return ca.vertcat(robot.x, robot.v)


def integrate(c: Command, a_e: ca.SX) -> ca.SX:
    """The expected trajectory one servo period on, at constant acceleration a_e:
    x_e + dt xd_e + dt^2 / 2 a_e on the positions, xd_e + dt a_e on the velocity (§3.4's
    double integral of xdd_e), moved by a fraction g = min(dt / anchor, 1) of the gap between
    the sensed state (x, xd) and the expected one at this tick. Open loop (``anchor`` None),
    the integral drifts from the robot in directions no controller above observes (a grasp's
    internal motion: the PD loops below then press against the grasp and undo its squeeze);
    anchored, it stays within about anchor times that drift's rate."""
    x_s, v_s = c.expected
    nx = x_s.shape[0]
    x_n = x_s + c.dt * rows(v_s, 0, nx) + 0.5 * c.dt**2 * rows(a_e, 0, nx)
    v_n = v_s + c.dt * a_e
    if c.node.anchor is not None:
        g = ca.fmin(c.dt / c.node.anchor, 1.0)
        x_n, v_n = x_n + g * (c.robot.x - x_s), v_n + g * (c.robot.v - v_s)
    return ca.vertcat(x_n, v_n)
