"""A spec's `simulation` section: how `robotgen simulate` runs the closed loop."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SimulationSettings:
    duration: float = 2.0
    dt: float = 1e-3
    start: tuple[float, ...] | None = None  # root positions at t = 0 (needs inverse kinematics)
    theta0: tuple[float, ...] | None = None  # or the leaf joint positions at t = 0
    initial_error: tuple[float, ...] = ()  # the plant starts at start + initial_error
    amplitude: tuple[float, ...] = ()  # x_d(t) = start + amplitude sin(2 pi frequency t)
    frequency: tuple[float, ...] = ()
    internal_forces: tuple[float, ...] = ()  # root f_i, if the root leaves some unresolved
