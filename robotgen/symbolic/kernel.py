"""The hand-over between the symbolic layer and the emitters."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import casadi as ca

from robotgen.model.parameters import RuntimeParameter
from robotgen.symbolic.schedule import Schedule, ScheduleBuilder

PARAMS = "params"  # the port of a module's run-time parameters, always a kernel's last input


@dataclass(frozen=True)
class Port:
    """A named input or output. Matrices are passed flattened in row-major order.

    The port named PARAMS carries the module's run-time parameters (robotgen.model.parameters):
    ``parameters`` lists them in struct order, and element k of the port is element k of
    their defaults concatenated; in C it is a ``const <name>_params *params``."""

    name: str
    rows: int
    cols: int = 1
    parameters: tuple[RuntimeParameter, ...] = ()
    matrix: bool = False  # two-dimensional even with one column (make_kernel's Matrix)

    @property
    def size(self) -> int:
        """rows x cols."""
        return self.rows * self.cols

    @property
    def is_matrix(self) -> bool:
        """Whether the port is shown as a matrix (declared so, or more than one column)."""
        return self.matrix or self.cols > 1


@dataclass(frozen=True, eq=False)
class Kernel:
    """One emitted function. ``function`` is a CasADi SX Function whose i-th input is a
    dense column of ``inputs[i].size`` and whose j-th output is a dense column of
    ``outputs[j].size`` holding the matrix row by row. ``graph`` is that Function or, for a
    kernel with a schedule (whose C is printed from the schedule's parts), what builds it on
    first use: a big tree's flattened kernels are CasADi's slowest step of a build and only
    tests and checks evaluate them."""

    name: str
    doc: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    graph: ca.Function | Callable[[], ca.Function]
    # The emitted C checks its inputs and results: status 1 (nothing written) when an input
    # is NaN or infinite, 2 (every output set to 0) when a result is not finite, such as
    # forward dynamics where M is not positive definite. For the functions a controller
    # calls every cycle on sensed data: servo steps and forward dynamics.
    guarded: bool = False
    # How the C evaluates ``function`` when its work repeats (robotgen.symbolic.schedule):
    # a prologue and loops; None: one straight-line program.
    schedule: Schedule | None = None
    # Why a guarded kernel's result cannot be finite at any state, when the model says so at
    # build time (a joint that moves no mass: M singular); its status 2 error names it.
    singular: str = ""

    @cached_property
    def function(self) -> ca.Function:
        """The kernel's CasADi Function, built on first use when it is a schedule's."""
        return self.graph if isinstance(self.graph, ca.Function) else self.graph()


def row_major(X: ca.SX) -> ca.SX:
    """X as a dense column holding it row by row (how every matrix leaves a kernel)."""
    return ca.densify(ca.reshape(X.T, X.numel(), 1))


Shape = tuple[int, int]


class Matrix(NamedTuple):
    """An output shape that stays a matrix with one column: a one-coordinate robot's (1, 1)
    mass matrix and (6, 1) Jacobian (a plain (n, 1) shape is a vector)."""

    rows: int
    cols: int


@dataclass(frozen=True, eq=False)
class ParameterSymbols:
    """The run-time parameters of one module as SX symbols, one column per parameter."""

    parameters: tuple[RuntimeParameter, ...]
    symbols: dict[str, ca.SX]

    @staticmethod
    def of(parameters: list[RuntimeParameter]) -> ParameterSymbols:
        """One SX symbol per run-time parameter, sized as the parameter."""
        return ParameterSymbols(tuple(parameters), {p.name: ca.SX.sym(p.name, p.size) for p in parameters})

    @property
    def vector(self) -> ca.SX:
        """Every parameter symbol stacked, in the parameters' order (the params port)."""
        return ca.vertcat(*[self.symbols[p.name] for p in self.parameters]) if self.parameters else ca.SX(0, 1)

    def port(self) -> tuple:
        """The (name, SX, shape) input of make_kernel for every kernel that reads a parameter."""
        return (PARAMS, self.vector, (self.vector.shape[0], 1), self.parameters)


NO_PARAMETERS = ParameterSymbols((), {})


def make_kernel(
    name: str,
    doc: str,
    inputs: Sequence[tuple],
    outputs: Sequence[tuple[str, ca.SX | None, Shape]],
    parameters: ParameterSymbols = NO_PARAMETERS,
    *,
    guarded: bool = False,
    schedule: ScheduleBuilder | None = None,
) -> Kernel:
    """The one way a kernel is built: ``inputs`` are (port name, SX column[, (rows, cols)
    the port shows, default a column]), ``outputs`` (port name, SX, (rows, cols), a Matrix for
    one that stays two-dimensional with one column); matrices leave row-major, and CasADi's
    common-subexpression elimination is on. A kernel whose outputs read a run-time parameter
    gets the PARAMS port last. ``schedule``: the loops the
    outputs were built by; their SX may be given as None, and are then ``schedule.outputs()``,
    flattened only when the kernel's function is first used."""
    for k, (port, expr, shape) in enumerate(outputs):
        if expr is None:
            assert schedule is not None and schedule.output_sizes[k] == shape[0] * shape[1], (name, port, shape)
        else:
            assert expr.shape == shape, (name, port, expr.shape, shape)

    def columns() -> list[ca.SX]:
        flat = schedule.outputs() if schedule is not None else []  # (an output given as None has a schedule)
        return [flat[k] if e is None else row_major(e) for k, (_, e, _) in enumerate(outputs)]

    if parameters.parameters and any(ca.depends_on(e, parameters.vector) for e in columns()):
        inputs = [*inputs, parameters.port()]
    ports_in = tuple(Port(i[0], *(i[2] if len(i) > 2 else (i[1].shape[0], 1)), *i[3:]) for i in inputs)

    def function() -> ca.Function:
        return ca.Function(
            name, [i[1] for i in inputs], columns(), [i[0] for i in inputs], [o[0] for o in outputs], {"cse": True}
        )

    ports_out = tuple(Port(o[0], *o[2], matrix=isinstance(o[2], Matrix)) for o in outputs)
    return Kernel(
        name,
        doc,
        ports_in,
        ports_out,
        function if schedule is not None else function(),
        guarded,
        schedule.finish([i[1] for i in inputs]) if schedule is not None else None,
    )
