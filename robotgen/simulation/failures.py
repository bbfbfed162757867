"""What ends a simulation: a loop that diverged, settings that cannot be simulated."""

from __future__ import annotations

import numpy as np

# a state entry beyond this is taken as divergence before it overflows
DIVERGED = 1e8


class SimulationError(ValueError):
    """The settings or the closed loop cannot be simulated: the user's to fix. ``field`` is
    the key of the simulation section the message is about (None: the spec as a whole)."""

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field


def format_values(values) -> str:
    """Values as [v1, v2, ...] to 4 significant digits."""
    return "[" + ", ".join(f"{v:.4g}" for v in np.asarray(values, float).ravel()) + "]"
