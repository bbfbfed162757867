"""Impedance control (Hogan 1985) on the controlled robot's coordinates x: the robot made to
behave as the target impedance

    M_d (xdd - xdd_d) + D (xd - xd_d) + K (x - x_d) = F_ext + F_d,

F_ext = -F_s the force of what the robot touches (F_s, rd's force term of eq 3.7: what the
robot exerts, sensed a period late) and F_d the force written at the node. Its robot's
M xdd + C xd + N = F + F_ext is given the acceleration the target asks,

    a* = xdd_d + M_d^-1 (F_d - F_s + D (xd_d - xd) + K (x_d - x)),
    F  = M a* + C xd + N + F_s,

and the trajectory (x_d, xd_d, a*) passes down. Without ``inertia`` the robot keeps its own
(M_d = M) and F_s cancels: F = M xdd_d + C xd + N + D (xd_d - xd) + K (x_d - x) + F_d, which
reads no force (the trajectory passed down is then (x_d, xd_d, xdd_d)). In steady contact
(xd = xdd = 0) the robot exerts F_s = K (x_d - x) + F_d. The controller absorbs the robot's
attributes (the node above sees M = C = N = 0)."""

from __future__ import annotations

import casadi as ca

from robotgen.model.laws import IMPEDANCE
from robotgen.model.parameter_struct import gain_parameter_name
from robotgen.model.system import ControlNode
from robotgen.symbolic.control.gains import written_matrix
from robotgen.symbolic.control.law import Command, TreeLaw, Written


def matrix(c: Command, key: str) -> ca.SX | ca.DM:
    """The impedance's stiffness, damping or inertia, as a run-time parameter or folded."""
    written = getattr(c.node.impedance, key)
    return written_matrix(c.parameters.symbols.get(gain_parameter_name(c.node, key)), written.value, written.form)


def write(c: Command) -> Written:
    """Impedance control (Hogan 1985): M_d e'' + D e' + K e = F_ext + F_d, the sensed force cancelled when M_d is
    set."""
    r = c.robot
    spring = matrix(c, "damping") @ (c.v_d - r.v) + matrix(c, "stiffness") @ c.position_error()
    if c.node.impedance.inertia is None:
        return Written(r.M @ c.a_d + r.C @ r.v + r.N + spring + c.F_d, c.x_d, c.v_d, c.a_d)
    F_s = c.sensed()[0]
    a = c.a_d + ca.solve(matrix(c, "inertia"), c.F_d - F_s + spring)
    return Written(r.M @ a + r.C @ r.v + r.N + F_s, c.x_d, c.v_d, a)


def reads_forces(node: ControlNode) -> bool:
    """Whether the node reads the sensed force: only with a target inertia M_d."""
    return node.impedance.inertia is not None


LAW = TreeLaw(IMPEDANCE, transparent=False, write=write, reads_forces=reads_forces)
