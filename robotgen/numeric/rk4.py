"""One classical Runge-Kutta (RK4) step of a second-order system in (position, velocity)
form, written once for every plant robotgen integrates: robotgen's plant in `simulate`, the
hand laws' plant, and the multi-rate tree's lifted loop, which must linearise the very step
the simulation takes. Plain arithmetic, so the same code runs on numpy arrays and on CasADi
graphs, and its operations come in one order (the same bits wherever it runs)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Rates = Callable[[Any, Any], Any]  # (x, v) -> the pair (x_dot, v_dot), indexable


def rk4_step(f: Rates, x: Any, v: Any, dt: Any) -> tuple[Any, Any]:
    """(x, v) one step of length dt on, with (x_dot, v_dot) = f(x, v) held to the step's inputs
    (a torque held over the period is f's, closed over)."""
    k1 = f(x, v)
    k2 = f(x + dt / 2 * k1[0], v + dt / 2 * k1[1])
    k3 = f(x + dt / 2 * k2[0], v + dt / 2 * k2[1])
    k4 = f(x + dt * k3[0], v + dt * k3[1])
    return (
        x + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
        v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]),
    )
