"""robotgen's own plant of a robot tree: the compiled module's plant_dynamics (the uncontrolled
tree's composite dynamics, Deno et al. 1990, eq 2.3) integrated by classical RK4, with the
spec's wall pushing on it (robotgen.simulation.wall_contact) and its payloads' masses set
mid-run (run-time parameters)."""

from __future__ import annotations

import numpy as np

from robotgen.model.simulation import ROBOTGEN_PLANT, Wall
from robotgen.numeric.rk4 import rk4_step
from robotgen.simulation.failures import DIVERGED, SimulationError, format_values
from robotgen.simulation.wall_contact import WallContact


class ModulePlant:
    """robotgen's own plant: the module's plant_dynamics, RK4 in (theta, v), torques held; the
    wall's push (if any) added to them at every stage, and the payload masses it is given
    passed to every plant function (run-time parameters)."""

    name = ROBOTGEN_PLANT
    note = "classical RK4 of plant_dynamics, one step per period"

    def __init__(self, module, theta: np.ndarray, theta_dot: np.ndarray, v: np.ndarray, n_ext: int):
        self.module, self.theta, self.v, self.n_ext = module, theta, v, n_ext
        self.wall: WallContact | None = None
        self.masses: dict[str, float] = {}  # run-time payload masses, by parameter name
        self._rates_now: np.ndarray | None = None  # theta_dot at the current state, once computed

    def set_wall(self, wall: Wall) -> None:
        """Put the simulation's wall in the plant."""
        self.wall = WallContact(self.module, wall)

    def set_payload_mass(self, payload: str, mass: float) -> None:
        """Change a run-time payload's mass [kg] from now on."""
        self.masses[f"{payload}_mass"] = mass
        self._rates_now = None

    def _rates(self, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
        """theta_dot (nq,) at (theta, v); at the current state computed once per step (the
        sensing, the wall and the forces all ask for it)."""
        now = theta is self.theta and v is self.v
        if now and self._rates_now is not None:
            return self._rates_now
        rates = self.module.plant_dynamics(theta, v, np.zeros(self.module.nq), **self.masses)[0]
        if now:
            self._rates_now = rates
        return rates

    def _pushed(self, theta: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The actuators' torques plus the wall's push at (theta, v)."""
        return tau if self.wall is None else tau + self.wall.torque(theta, self._rates(theta, v))

    def sensed(self) -> tuple[np.ndarray, np.ndarray]:
        """Leaf positions theta (nq,) and rates theta_dot (nq,) of the plant now."""
        return self.theta, self._rates(self.theta, self.v)

    def position(self, theta: np.ndarray) -> np.ndarray:
        """The root's external positions at leaf positions theta (nq,), by the module's plant_position."""
        return self.module.plant_position(theta)[: self.n_ext]

    def internal_forces(self, tau: np.ndarray) -> np.ndarray:
        """The plant's internal forces under leaf torques tau (nq,), the wall's push included."""
        return self.module.plant_internal_forces(
            self.theta, self.v, self._pushed(self.theta, self.v, tau), **self.masses
        )

    def sensed_forces(self, tau_before: np.ndarray) -> np.ndarray:
        """What the leaves exert through the grasps and on the wall now, the last torques still
        applied: plant_sensed_forces under the actuators' and the wall's torques, less the
        wall's push (the leaves exert its opposite)."""
        pushed = self._pushed(self.theta, self.v, tau_before)
        return self.module.plant_sensed_forces(self.theta, self.v, pushed, **self.masses) - (pushed - tau_before)

    def wall_force(self) -> float:
        """The wall's normal force [N] on its point now (a TypeError without a wall)."""
        if self.wall is None:
            raise TypeError("the plant has no wall")
        return self.wall.normal_force(*self.sensed())

    def record(self, t: float) -> None:
        """robotgen's plant records no contacts."""
        pass

    def step(self, tau: np.ndarray, dt: float, when: str) -> None:
        """One period on; ``when`` says which, for the message if the loop diverges."""
        theta_next, v_next = _rk4(
            lambda th, vel: self.module.plant_dynamics(th, vel, self._pushed(th, vel, tau), **self.masses),
            self.theta,
            self.v,
            dt,
        )
        if not (np.all(np.abs(theta_next) < DIVERGED) and np.all(np.abs(v_next) < DIVERGED)):
            raise SimulationError(
                f"the closed loop diverged {when}: the state before the blow-up was theta = "
                f"{format_values(self.theta)}, root velocity = {format_values(self.v)}, torque = "
                f"{format_values(tau)}; the gains are too high for dt = {dt:g} s or the loop is unstable: lower kp "
                "and kv, or dt"
            )
        self.theta, self.v = theta_next, v_next
        self._rates_now = None


def _rk4(f, theta, v, dt):
    """One classical RK4 step of (theta_dot, v_dot) = f(theta, v); NaN where a stage left the finite numbers."""
    with np.errstate(all="ignore"):  # a diverging loop overflows; run() reports it
        try:
            return rk4_step(f, theta, v, dt)
        except FloatingPointError:  # the checked plant refuses a stage that is not finite
            return np.full_like(theta, np.nan), np.full_like(v, np.nan)
