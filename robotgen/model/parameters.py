"""Run-time parameters: spec numbers the emitted code reads when it runs instead of folding
them into constants. Controller gains are run-time by default (`gains: folded` folds them);
a formulas leaf's parameter or a rigid payload's mass is run-time when the spec writes it as
`{runtime: value}`. In C they are the fields of one struct, `<name>_params`, with the spec's
values as defaults in the header; in Python, keyword arguments with those defaults.

A parameter declares the values it may take (``Bounds``): `robotgen check` refuses a spec
value outside them, and the emitted module refuses a value given at run time, with the same
message (``Bounds.violation``; the C twin is templates/params_check.c.jinja).

Folding is faster (the compiler multiplies by known numbers and drops zeros); a run-time
parameter costs a load and the full product (docs/python-api.md, docs/c-api.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# A positive definite matrix parameter is symmetric to this fraction of max(1, its largest
# |entry|), and every pivot of its L D L^T factorisation is above this fraction of it.
SYMMETRY_TOLERANCE = 1e-12
PIVOT_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Violation:
    """Where a value leaves its bounds: ``index`` () for the value as a whole, (i,) an entry
    of a vector, (i, j) of a matrix; ``message`` says what is wrong."""

    index: tuple[int, ...]
    message: str


@dataclass(frozen=True)
class Bounds:
    """The values a run-time parameter may take. Every entry is finite, and

    minimum:   every entry above it (exclusive) or at least it; None: no lower bound.
    maximum:   every entry below it (exclusive_maximum) or at most it; None: no upper bound.
    positive_definite: a square matrix, symmetric and positive definite (to SYMMETRY_TOLERANCE
               and PIVOT_TOLERANCE); its entries have no other bounds.
    what:      names one entry in messages ("gain", "forgetting factor"), or the matrix ("Q").
    note:      said after the rule in parentheses ("eq 37")."""

    what: str
    minimum: float | None = None
    exclusive: bool = False
    maximum: float | None = None
    exclusive_maximum: bool = False
    positive_definite: bool = False
    note: str = ""

    @staticmethod
    def positive(what: str, note: str = "") -> Bounds:
        """Bounds of a value that must be above 0."""
        return Bounds(what, minimum=0.0, exclusive=True, note=note)

    @staticmethod
    def definite(what: str, note: str = "") -> Bounds:
        """Bounds of a matrix that must be symmetric positive definite."""
        return Bounds(what, positive_definite=True, note=note)

    @property
    def suffix(self) -> str:
        """The note as a message's suffix: " (note)", or empty."""
        return f" ({self.note})" if self.note else ""

    @property
    def noun(self) -> str:
        """What one entry is called in a message."""
        return f"{self.what} entry" if self.positive_definite else self.what

    @property
    def relation(self) -> str:
        """What every entry must be, after "must be": "positive", "in (0, 1]", ... ("" when
        the entries have no bounds but finiteness)."""
        low, high = self.minimum, self.maximum
        if low is not None and high is not None:
            return f"in {'(' if self.exclusive else '['}{low:g}, {high:g}{')' if self.exclusive_maximum else ']'}"
        if low is not None:
            if self.exclusive:
                return "positive" if low == 0 else f"greater than {low:g}"
            return f"at least {low:g}"
        if high is not None:
            return f"below {high:g}" if self.exclusive_maximum else f"at most {high:g}"
        return ""

    @property
    def text(self) -> str:
        """The range in words, for headers and info(): "positive", "in (0, 1]", "symmetric
        positive definite"."""
        if self.positive_definite:
            return "symmetric positive definite"
        return self.relation or "finite"

    def inside(self, v: float) -> bool:
        """Whether one finite entry is within minimum and maximum."""
        if self.minimum is not None and not (v > self.minimum if self.exclusive else v >= self.minimum):
            return False
        return self.maximum is None or (v < self.maximum if self.exclusive_maximum else v <= self.maximum)

    def violation(self, value) -> Violation | None:
        """The first way ``value`` (the parameter's shape) leaves these bounds, or None. The
        entries are read in row-major order; a matrix is checked for symmetry, then factored."""
        a = np.asarray(value, dtype=float)
        flat = a.ravel()
        for k, v in enumerate(flat):
            index = np.unravel_index(k, a.shape) if a.shape else ()
            if not math.isfinite(v):
                return Violation(tuple(map(int, index)), f"{self.noun} {v:g} must be finite{self.suffix}")
            if not self.inside(v):
                return Violation(tuple(map(int, index)), f"{self.noun} {v:g} must be {self.relation}{self.suffix}")
        if self.positive_definite:
            return _definite(self, a)
        return None


def _definite(bounds: Bounds, a: np.ndarray) -> Violation | None:
    """Symmetry, then the pivots of L D L^T (rows in order, each sum from k = 0 up) as the
    emitted C computes them (templates/params_check.c.jinja), so that both decide alike; the
    message quotes the smallest eigenvalue (numpy's, in both)."""
    n = a.shape[0]
    scale = max(1.0, float(np.abs(a).max()))
    for i in range(n):
        for j in range(i + 1, n):
            if abs(a[i, j] - a[j, i]) > SYMMETRY_TOLERANCE * scale:
                return Violation(
                    (i, j),
                    f"{bounds.what} must be symmetric{bounds.suffix}: entry ({i}, {j}) = "
                    f"{a[i, j]:g} but ({j}, {i}) = {a[j, i]:g}",
                )
    L = [[0.0] * n for _ in range(n)]
    d = [0.0] * n
    for j in range(n):
        s = float(a[j, j])
        for k in range(j):
            s -= L[j][k] * L[j][k] * d[k]
        d[j] = s
        if not s > PIVOT_TOLERANCE * scale:
            return Violation((), definite_message(bounds, float(np.linalg.eigvalsh(a)[0])))
        for i in range(j + 1, n):
            s = float(a[i, j])
            for k in range(j):
                s -= L[i][k] * L[j][k] * d[k]
            L[i][j] = s / d[j]
    return None


def definite_message(bounds: Bounds, smallest: float) -> str:
    """The message for a matrix that is not positive definite, with its smallest eigenvalue."""
    return f"{bounds.what} must be positive definite{bounds.suffix}: its smallest eigenvalue is {smallest:.3g}"


# How a spec writes a matrix gain on n coordinates (kp, kv, an impedance's stiffness): a number
# (times I), a list (the diagonal) or n rows; its run-time parameter has that shape
SCALAR_GAIN, DIAGONAL_GAIN, MATRIX_GAIN = "scalar", "diagonal", "matrix"


def written_shape(form: str, K: np.ndarray) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """(shape, row-major values) of the run-time parameter of matrix ``K`` (n x n) written in
    ``form``: () its [0, 0], (n,) its diagonal, (n, n) all of it."""
    K = np.asarray(K, dtype=float)
    shape, values = {
        SCALAR_GAIN: ((), (K[0, 0],)),
        DIAGONAL_GAIN: ((K.shape[0],), tuple(np.diag(K))),
        MATRIX_GAIN: (K.shape, tuple(K.ravel())),
    }[form]
    return shape, tuple(map(float, values))


@dataclass(frozen=True)
class RuntimeParameter:
    """One field of the parameter struct.

    name:    C field and Python keyword, <node>_<key> (an identifier).
    shape:   () a number, (n,) a vector (a per-axis gain), (n, n) a matrix (row-major).
    default: the spec's value, row-major.
    doc:     what it is, for the header and the stub.
    bounds:  the values it may take (None: any number), checked by `robotgen check` and when
             the emitted module is given one."""

    name: str
    shape: tuple[int, ...]
    default: tuple[float, ...]
    doc: str
    bounds: Bounds | None = None

    @property
    def size(self) -> int:
        """The number of values (1 for a scalar)."""
        return int(np.prod(self.shape)) if self.shape else 1

    def __post_init__(self):
        assert len(self.default) == self.size, (self.name, self.shape, self.default)
        assert (
            self.bounds is None
            or not self.bounds.positive_definite
            or (len(self.shape) == 2 and self.shape[0] == self.shape[1])
        ), (self.name, self.shape)
        assert self.bounds is None or self.bounds.violation(np.reshape(self.default, self.shape)) is None, (
            self.name,
            self.default,
            self.bounds,
        )
