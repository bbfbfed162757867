"""PD plus feedforward (Deno et al. 1990, eq 2.10): F = M xdd_d + C xd_d + N + Kv e' + Kp e +
F_d, the desired trajectory passed down unchanged; the robot's attributes are absorbed."""

from __future__ import annotations

from robotgen.model.laws import PD_FEEDFORWARD
from robotgen.symbolic.control.law import Command, TreeLaw, Written


def write(c: Command) -> Written:
    """PD + feedforward: F = M a_d + C v_d + N + Kv e' + Kp e + F_d (the model at the desired velocity)."""
    r = c.robot
    F = r.M @ c.a_d + r.C @ c.v_d + r.N + c.feedback(c.position_error()) + c.F_d
    return Written(F, c.x_d, c.v_d, c.a_d)


LAW = TreeLaw(PD_FEEDFORWARD, transparent=False, write=write)
