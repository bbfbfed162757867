"""Run-time parameters: spec numbers the emitted code reads when it runs instead of folding
them into constants. Controller gains are run-time by default (`gains: folded` folds them);
a formulas leaf's parameter or a rigid payload's mass is run-time when the spec writes it as
`{runtime: value}`. In C they are the fields of one struct, `<name>_params`, with the spec's
values as defaults in the header; in Python, keyword arguments with those defaults.

Folding is faster (the compiler multiplies by known numbers and drops zeros); a run-time
parameter costs a load and the full product (docs/python-api.md, docs/c-api.md)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RuntimeParameter:
    """One field of the parameter struct.

    name:    C field and Python keyword, <node>_<key> (an identifier).
    shape:   () a number, (n,) a vector (a per-axis gain), (n, n) a matrix (row-major).
    default: the spec's value, row-major.
    doc:     what it is, for the header and the stub."""

    name: str
    shape: tuple[int, ...]
    default: tuple[float, ...]
    doc: str

    @property
    def size(self) -> int:
        return int(np.prod(self.shape)) if self.shape else 1

    def __post_init__(self):
        assert len(self.default) == self.size, (self.name, self.shape, self.default)
