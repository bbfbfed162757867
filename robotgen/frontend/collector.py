"""The error collector every part of the spec front end shares: located messages
(FILE:LINE:COL, at a key or at a value), numbers and constant expressions, poses, formula
expressions and name checks. Nothing is returned from a spec with errors."""

from __future__ import annotations

import ast
import keyword
from typing import overload

import numpy as np

from robotgen.errors import Location, UserError
from robotgen.frontend.document import Document, Path, format_path
from robotgen.model.expression import CONSTANTS, FUNCTIONS, Expr, parse_constant, parse_expression
from robotgen.model.parameters import Bounds
from robotgen.model.transforms import xyz_rpy


class Collector:
    """Collects located errors and warnings while model objects are built from ``doc.data``."""

    def __init__(self, doc: Document):
        self.doc = doc
        self.errors: list[UserError] = []
        self.warnings: list[str] = []
        self.dependencies: list[str] = []

    def error(self, location: Location, path: Path, message: str) -> None:
        """Record an error at ``location``, prefixed with the spec path of the value it concerns."""
        self.errors.append(UserError(location, f"{format_path(self.doc.data, path)}: {message}"))

    def at_key(self, path: Path, message: str) -> None:
        """Record an error located at the key of ``path``."""
        self.error(self.doc.source.key(path), path, message)

    def at_value(self, path: Path, message: str) -> None:
        """Record an error located at the value of ``path``."""
        self.error(self.doc.source.value(path), path, message)

    def text_location(self, path: Path, value: object) -> tuple[Location, bool]:
        """Where a value's text starts, and whether its columns are exact (a plain string) or only its line's."""
        if isinstance(value, str):
            return self.doc.source.text_start(path, value)
        return self.doc.source.value(path), True

    def constant(self, path: Path, value: object, *, minimum: float | None = None, exclusive: bool = False) -> float:
        """A constant (a number or a constant expression such as pi/2), checked against ``minimum``; 0.0 after an
        error."""
        location, exact = self.text_location(path, value)
        try:
            number = parse_constant(value, location, exact_columns=exact)
        except UserError as error:
            self.error(error.location, path, error.message)
            return 0.0
        if minimum is not None and (number <= minimum if exclusive else number < minimum):
            shown = f"{value!r} = {number:g}" if isinstance(value, str) else f"{number!r}"
            relation = "less than or equal to" if exclusive else "less than"
            self.at_value(path, f"{shown} is {relation} the minimum of {minimum:g}")
        return number

    def parameter(self, path: Path, value: object, bounds: Bounds | None = None) -> tuple[float, bool]:
        """A number (within ``bounds``, if given), or ``{runtime: number}``: (its value,
        whether it is a run-time parameter)."""
        if isinstance(value, dict):
            path, value, runtime = path + ("runtime",), value["runtime"], True
        else:
            runtime = False
        return (self.constant(path, value) if bounds is None else self.bounded(path, value, bounds)), runtime

    def bounded(self, path: Path, value: object, bounds: Bounds) -> float:
        """A number within ``bounds``: outside them, the message a run-time parameter with
        these bounds gives for the same value (robotgen.model.parameters)."""
        number = self.constant(path, value)
        self.within(path, number, bounds)
        return number

    def within(self, path: Path, value, bounds: Bounds, entry=None) -> bool:
        """Whether ``value`` (a number, or the array a spec entry gives) is within ``bounds``;
        if not, the first violation is reported at ``path`` + ``entry(index)`` (an entry's
        own position; default: its index as given, None: at ``path``'s key)."""
        violation = bounds.violation(value)
        if violation is None:
            return True
        below = violation.index if entry is None else entry(violation.index)
        if below is None:
            self.at_key(path, violation.message)
        else:
            self.at_value(path + tuple(below), violation.message)
        return False

    @overload
    def optional(self, mapping: dict, path: Path, key: str, default: float, **bounds) -> float: ...

    @overload
    def optional(self, mapping: dict, path: Path, key: str, default: None, **bounds) -> float | None: ...

    def optional(self, mapping: dict, path: Path, key: str, default: float | None, **bounds) -> float | None:
        """mapping[key] read as a constant, or ``default`` when the key is absent."""
        if key not in mapping:
            return default
        return self.constant(path + (key,), mapping[key], **bounds)

    def vector(self, path: Path, values: list | None, default) -> np.ndarray:
        """A vector of constants, or ``default`` when absent."""
        if values is None:
            return np.array(default, dtype=float)
        return np.array([self.constant(path + (i,), v) for i, v in enumerate(values)])

    def pose(self, path: Path, pose: dict | None) -> np.ndarray:
        """A pose {xyz [m], rpy [rad]} as a (4, 4) homogeneous transform; a missing part is zero."""
        pose = pose or {}
        return xyz_rpy(
            self.vector(path + ("xyz",), pose.get("xyz"), (0, 0, 0)),
            self.vector(path + ("rpy",), pose.get("rpy"), (0, 0, 0)),
        )

    def expression(self, path: Path, value: object, names: set[str]) -> Expr:
        """A formula expression over ``names``, parsed and located; after an error, the constant 0
        (like ``constant``'s 0.0: the error is collected and the spec refused)."""
        location, exact = self.text_location(path, value)
        try:
            return parse_expression(value, location, names, exact_columns=exact)
        except UserError as error:
            self.error(error.location, path, error.message)
            return Expr("0", ast.Constant(0.0), location)

    def check_names(self, path: Path, entries: list[tuple[str, Path, str]]) -> None:
        """Names of coordinates, velocities and parameters: distinct, not reserved."""
        owner: dict[str, str] = {}
        for name, where, kind in entries:
            if name in FUNCTIONS or name in CONSTANTS:
                self.at_key(
                    where, f"{kind} '{name}' shadows the {'function' if name in FUNCTIONS else 'constant'} '{name}'"
                )
            elif keyword.iskeyword(name):
                self.at_key(where, f"{kind} '{name}' is a reserved word")
            elif name in owner:
                self.at_key(where, f"{kind} '{name}' is already a {owner[name]} name")
            owner.setdefault(name, kind)

    def vector_of_expressions(self, path: Path, values: list, length: int | None, names: set[str]) -> tuple[Expr, ...]:
        """A list of formula expressions, checked to have ``length`` entries (nq) when given."""
        if length is not None and len(values) != length:
            self.at_key(path, f"expected {length} entries (nq = {length}), got {len(values)}")
        return tuple(self.expression(path + (i,), v, names) for i, v in enumerate(values))

    def check_unique(self, owner: dict[str, str], names, robot: str, path: Path, kind: str, fix: str) -> None:
        """Check that ``names`` of ``robot`` belong to no other robot (owner: name -> robot), then claim them."""
        for n in names:
            if n in owner and owner[n] != robot:
                self.at_value(
                    path,
                    f"{kind} '{n}' of '{robot}' is also one of '{owner[n]}'; "
                    f"names must be unique across the robots: {fix}",
                )
                return
        for n in names:
            owner.setdefault(n, robot)

    def rectangle(
        self, path: Path, rows: list, n_rows: int | None, n_cols: int, names: set[str], columns: str
    ) -> tuple[tuple[Expr, ...], ...]:
        """A matrix of formula expressions: n_rows rows (when given) of n_cols entries each."""
        if n_rows is not None and len(rows) != n_rows:
            self.at_key(path, f"expected {n_rows} rows (one per node coordinate), got {len(rows)}")
        for i, row in enumerate(rows):
            if len(row) != n_cols:
                self.at_value(path + (i,), f"expected {n_cols} entries in each row (one per {columns}), got {len(row)}")
        return tuple(self.vector_of_expressions(path + (i,), row, None, names) for i, row in enumerate(rows))

    def per_joint(self, path: Path, value: object, n: int, what: str, *, positive: bool) -> np.ndarray:
        """A number (the same for every joint) or a list of n numbers."""
        if not isinstance(value, list):
            values = np.full(n, self.constant(path, value))
            if positive and values[0] <= 0:
                self.at_value(path, f"{what} {values[0]:g} must be positive")
            return values
        if len(value) != n:
            self.at_key(path, f"expected {n} entries (one per joint), got {len(value)}")
            return np.ones(n)
        values = np.array([self.constant(path + (i,), v) for i, v in enumerate(value)])
        for i, v in enumerate(values):
            if positive and v <= 0:
                self.at_value(path + (i,), f"{what} {v:g} must be positive")
        return values
