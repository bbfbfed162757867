"""The hand's way to a target pose under position control through rates (Whitney 1972, eqs
11-18), in the two forms a resolved-rate module offers, for plots and checks:

- ``exponential``: ``position_step(q, target)``, T the spec's fixed horizon, re-planned at
  every call: the remaining error shrinks by 1 - dt / T per period, about exp(-t / T).
- ``arrival``: ``arrival_step(q, target, remaining)`` with remaining = arrival_time - t, eq 11
  with a new T at every call: a straight line at constant speed, arriving at arrival_time.

The joints follow the commanded rates exactly, as an ideal joint-rate servo: each call's
rates are held over one control period dt (eq 12, theta = theta_i + integral of theta_dot).
``module`` is a built module with both steps: a chain's (q, a 4x4 target pose) or a
composite robot's (theta, its external coordinates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EXPONENTIAL = "exponential"
ARRIVAL = "arrival"


@dataclass
class ApproachPath:
    """One approach to a target as sampled: times t [s], joint positions q, the step's error output and the rate
    scale at each sample."""

    approach: str  # exponential | arrival
    t: np.ndarray  # (steps + 1,) [s]
    q: np.ndarray  # (steps + 1, n) joint positions at t
    error: np.ndarray  # (steps + 1, m) the step's error output at q (target minus hand)
    rate_scale: np.ndarray  # (steps + 1,) 1, or below 1 where the rate limits slowed the hand

    def distance(self, rows: slice = slice(0, 3)) -> np.ndarray:
        """|error[rows]| at each t: by default a chain's position error [m]."""
        return np.linalg.norm(self.error[:, rows], axis=1)


def approach_paths(
    module, q0, target, arrival_time: float, dt: float, duration: float | None = None
) -> tuple[ApproachPath, ApproachPath]:
    """(exponential, arrival) from joint positions q0 to ``target`` over ``duration``
    (default arrival_time) at control period dt. The spec's ``arrival.minimum_remaining``
    should be dt, so that the last call before arrival_time carries the hand onto the
    target."""
    steps = int(round((arrival_time if duration is None else duration) / dt))
    q0 = np.asarray(q0, dtype=float)

    def run(approach: str, step) -> ApproachPath:
        q = np.empty((steps + 1, q0.size))
        q[0] = q0
        errors, scales = [], []
        for k in range(steps + 1):
            qd, error, scale = step(q[k], k * dt)
            errors.append(error)
            scales.append(scale)
            if k < steps:
                q[k + 1] = q[k] + dt * qd
        return ApproachPath(approach, np.arange(steps + 1) * dt, q, np.array(errors), np.array(scales))

    def exponential(q, t):
        out = module.position_step(q, target)
        return out[0], out[1], 1.0

    def arrival(q, t):
        out = module.arrival_step(q, target, arrival_time - t)
        return out[0], out[1], float(out[2][0])

    return run(EXPONENTIAL, exponential), run(ARRIVAL, arrival)
