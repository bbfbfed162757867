"""PD (Deno et al. 1990, §3.4 and §4.3): F = F_d + Kp e + Kv e', the desired trajectory passed
down; a stiffness, like muscle coactivation, so the node above sees the robot's own M, C, N."""

from __future__ import annotations

from robotgen.model.laws import PD
from robotgen.symbolic.control.law import Command, TreeLaw, Written


def write(c: Command) -> Written:
    """PD: F = F_d + Kv e' + Kp e, no model of the robot."""
    return Written(c.F_d + c.feedback(c.position_error()), c.x_d, c.v_d, c.a_d)


LAW = TreeLaw(PD, transparent=True, write=write)
