"""The hand-over between the symbolic layer and the emitters."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Port:
    """A named input or output. Matrices are passed flattened in row-major order."""

    name: str
    rows: int
    cols: int = 1

    @property
    def size(self) -> int:
        return self.rows * self.cols

    @property
    def is_matrix(self) -> bool:
        return self.cols > 1


@dataclass(frozen=True, eq=False)
class Kernel:
    """One emitted function. ``function`` is a CasADi SX Function whose i-th input is a
    dense column of ``inputs[i].size`` and whose j-th output is a dense column of
    ``outputs[j].size`` holding the matrix row by row."""

    name: str
    doc: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    function: ca.Function
