"""Hybrid force/position control (Raibert and Craig 1981) on the controlled robot's coordinates
x: a selection matrix S = diag(s), s_i 1 on a position-controlled coordinate and 0 on a
force-controlled one, splits the task. The position coordinates follow x_d as under computed
torque; the force coordinates exert the force F_d written at the node, with a PI loop on
the sensed force F_s (rd's force term, eq 3.7: what the robot exerts, sensed a period late)
and the velocity damped:

    a* = S (xdd_d + Kv (xd_d - xd) + Kp (x_d - x)) - (I - S) Kv xd,
    e  = (I - S) (F_d - F_s),   z+ = z + dt e,
    F  = M a* + C xd + N + F_d + kf e + ki z+.

z, the force error's integral, is the controller's state (zero after a reset). In steady
contact along the force coordinates the robot exerts F_s = F_d there: the feedforward F_d
alone does it on an exact model; kf speeds the loop and ki removes what the model misses
(a friction, a gravity error). The trajectory (x_d, xd_d, a*) passes down; the controller
absorbs the robot's attributes."""

from __future__ import annotations

import casadi as ca

from robotgen.model.laws import HYBRID
from robotgen.model.parameter_struct import gain_parameter_name
from robotgen.model.system import ControlNode
from robotgen.symbolic.control.gains import gain
from robotgen.symbolic.control.law import Command, TreeLaw, Written
from robotgen.symbolic.node import NodeGraph


def selection(c: Command) -> ca.SX | ca.DM:
    """The selection S as a diagonal matrix: a run-time parameter or folded."""
    p = c.parameters.symbols.get(gain_parameter_name(c.node, "selection"))
    return ca.diag(p) if p is not None else ca.diag(ca.DM(c.node.hybrid.selection))


def setting(c: Command, key: str) -> ca.SX | float:
    """kf or ki: a run-time parameter or folded."""
    p = c.parameters.symbols.get(gain_parameter_name(c.node, key))
    return p if p is not None else getattr(c.node.hybrid, key)


def write(c: Command) -> Written:
    """Hybrid control (Raibert and Craig 1981): computed torque on S's coordinates, F_d with a PI loop on I - S's."""
    r = c.robot
    S = selection(c)
    free = ca.DM.eye(S.shape[0]) - S  # I - S: the force-controlled coordinates
    Kp, Kv = gain(c.node, "kp", c.parameters), gain(c.node, "kv", c.parameters)
    a = S @ (c.a_d + Kv @ (c.v_d - r.v) + Kp @ c.position_error()) - free @ (Kv @ r.v)
    e = free @ (c.F_d - c.sensed()[0])
    z = c.law_state + c.dt * e
    F = r.M @ a + r.C @ r.v + r.N + c.F_d + setting(c, "kf") * e + setting(c, "ki") * z
    return Written(F, c.x_d, c.v_d, a, z)


def force_integral_start(robot: NodeGraph) -> ca.SX:
    """The force error's integral starts at zero."""
    return ca.SX.zeros(robot.sig.n_external)


def reads_forces(node: ControlNode) -> bool:
    """A hybrid node always reads the force its robot senses."""
    return True


LAW = TreeLaw(HYBRID, transparent=False, write=write, state=force_integral_start, reads_forces=reads_forces)
