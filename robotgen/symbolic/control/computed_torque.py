"""Computed torque (Deno et al. 1990, §3.4): the controller integrates an expected trajectory
from xdd_e = xdd_d + Kv (xd_d - xd) + Kp (x_d - x) and writes F = M xdd_e + C xd + N + F_d
to the robot, whose attributes it absorbs (the node above sees M = C = N = 0)."""

from __future__ import annotations

from robotgen.model.laws import COMPUTED_TORQUE
from robotgen.symbolic.control.law import Command, TreeLaw, Written, expected_start, integrate


def write(c: Command) -> Written:
    """Computed torque (eq 2.10): F = M (a_d + Kv e' + Kp e) + C v + N + F_d on the robot's coordinates."""
    a_e = c.a_d + c.feedback(c.position_error())
    r = c.robot
    F = r.M @ a_e + r.C @ r.v + r.N + c.F_d
    x_e, v_e = c.expected
    return Written(F, x_e, v_e, a_e, integrate(c, a_e))


LAW = TreeLaw(COMPUTED_TORQUE, transparent=False, write=write, state=expected_start)
