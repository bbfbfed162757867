"""Feedforward (Deno et al. 1990, §3.4): computed torque without position feedback, F = M xdd_e
+ C xd + N + F_d with xdd_e = xdd_d + Kv (xd_d - xd) (Kp unused; the spec's gains default to
zero), integrating the expected trajectory the same way."""

from __future__ import annotations

from robotgen.model.laws import FEEDFORWARD
from robotgen.symbolic.control.law import Command, TreeLaw, Written, expected_start, integrate


def write(c: Command) -> Written:
    """Feedforward: F = M a_d + C v + N + F_d, no feedback on the error."""
    a_e = c.a_d + c.feedback(None)
    r = c.robot
    F = r.M @ a_e + r.C @ r.v + r.N + c.F_d
    x_e, v_e = c.expected
    return Written(F, x_e, v_e, a_e, integrate(c, a_e))


LAW = TreeLaw(FEEDFORWARD, transparent=False, write=write, state=expected_start)
