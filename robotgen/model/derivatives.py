"""Which derivative functions a module offers (the spec's `derivatives` section): the
partial derivatives of the dynamics, M^-1, and one step of a discrete-time model with its
Jacobians, for trajectory optimisation and model-predictive control."""

from __future__ import annotations

from dataclasses import dataclass

SEMI_IMPLICIT_EULER = "semi_implicit_euler"
RK4 = "rk4"
INTEGRATORS = (SEMI_IMPLICIT_EULER, RK4)
# Left out unless asked for above this many joints: the derivative graphs grow as n^2 to n^3.
DEFAULT_MAX_DOF = 12


@dataclass(frozen=True)
class DerivativeSettings:
    """``include`` None: included for a leaf robot of at most DEFAULT_MAX_DOF coordinates;
    ``integrator`` is the discrete model's (x = (q, qd), tau held over the step):
    semi_implicit_euler: qd+ = qd + dt qdd(q, qd, tau), q+ = q + dt qd+;
    rk4: the classical fourth-order Runge-Kutta step of (qd, qdd(q, qd, tau))."""

    include: bool | None = None
    integrator: str = SEMI_IMPLICIT_EULER

    def included(self, nq: int) -> bool:
        """Whether the derivative functions are built for a leaf of ``nq`` coordinates."""
        return self.include if self.include is not None else nq <= DEFAULT_MAX_DOF

    def when_asked(self) -> DerivativeSettings | None:
        """For a root law's chain: only when the spec says include: true (they would add to
        a controller module's build what its user did not ask for)."""
        return self if self.include else None
