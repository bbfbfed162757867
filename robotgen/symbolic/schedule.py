"""A kernel whose work repeats, printed as loops: a straight-line prologue fills local arrays,
then loops apply one small body to slices of them, so the emitted C holds each repeated part
once. Straight-line code grows with its operations; a 7-dof arm's dynamics derivatives
unrolled overflow the instruction cache, and a kernel that streams its code from L2 runs
slower than one that fits (docs/performance-log.md). The loops here: the derivative recursion
(rigid_body/derivative_loops), a long chain's or tree's dynamics (rigid_body/chain_loops) and
products with M^-1 (rigid_body/cholesky).

The schedule is the one source of the kernel's graph: ``outputs()`` applies each loop's body to
SX slices in order, and is the kernel's CasADi function, so the graph and the loops cannot
differ. Adding a loop only checks that what it reads was written: a build prints the loops and
never needs the flattened graph, which takes a large tree's build noticeable time."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca

LOCAL, OUTPUT, INPUT = "local", "output", "input"
ONCE, RANGE, DESCENDING = "once", "range", "descending"
BELOW, ABOVE, ABOVE_DESCENDING = "below", "above", "above descending"
PAIRS = "pairs"
"""Index spaces over n: ONCE i = 0 (a straight-line block); RANGE i = 0, ..., n-1;
DESCENDING i = n-1, ..., 0; pairs with j outer: BELOW j = 0, ..., n-1 and i in (j, n); ABOVE
j = 1, ..., n-1 and i < j; ABOVE_DESCENDING the same with j = n-1, ..., 1; PAIRS the (i, j)
of a listed table, in its order (a tree's ancestor pairs)."""


@dataclass(frozen=True)
class Slice:
    """Elements ``offset + i * i_stride + j * j_stride + e * step`` (e = 0, 1, ...) of a local
    array, an output port or (read by a loop) an input port (``index`` numbers it among the
    locals, the outputs or the inputs)."""

    kind: str
    index: int
    offset: int = 0
    i_stride: int = 0
    j_stride: int = 0
    step: int = 1
    i_table: tuple[int, ...] = ()  # when given, i_table[i] takes i's place (a tree's parent)

    def elements(self, count: int, i: int, j: int) -> list[int]:
        """The array elements of iteration (i, j): ``count`` of them, ``step`` apart."""
        start = self.offset + (self.i_table[i] if self.i_table else i) * self.i_stride + j * self.j_stride
        return [start + e * self.step for e in range(count)]


@dataclass(frozen=True, eq=False)
class Loop:
    """One loop: a body applied to slices of local arrays over an index space (RANGE, PAIRS, ONCE)."""

    body: ca.Function  # SX; dense column inputs and outputs
    space: str
    n: int
    reads: tuple[Slice, ...]  # one per body input (locals, outputs written before, array inputs)
    writes: tuple[Slice, ...]  # one per body output
    pairs: tuple[tuple[int, int], ...] = ()  # the space PAIRS

    def iterations(self) -> list[tuple[int, int]]:
        """The (i, j) of each iteration, in order."""
        n = self.n
        if self.space == PAIRS:
            return list(self.pairs)
        if self.space == ONCE:
            return [(0, 0)]
        if self.space == RANGE:
            return [(i, 0) for i in range(n)]
        if self.space == DESCENDING:
            return [(i, 0) for i in range(n - 1, -1, -1)]
        if self.space == BELOW:
            return [(i, j) for j in range(n) for i in range(j + 1, n)]
        if self.space == ABOVE:
            return [(i, j) for j in range(n) for i in range(j)]
        if self.space == ABOVE_DESCENDING:
            return [(i, j) for j in range(n - 1, 0, -1) for i in range(j)]
        raise ValueError(f"unknown index space {self.space!r}")


@dataclass(frozen=True, eq=False)
class Stage:
    """Straight-line work that other kernels of the module repeat (a chain's kinematics): the
    emitted C holds it once, as a static helper that each kernel calls before its prologue."""

    name: str
    function: ca.Function  # the kernel inputs it reads -> one column per write
    inputs: tuple[int, ...]  # which of the kernel's inputs those are
    writes: tuple[int, ...]  # the locals it fills, whole
    names: tuple[str, ...]  # of its outputs (the helper's parameters)


@dataclass(frozen=True, eq=False)
class Schedule:
    """A kernel as a prologue and loops over local arrays, with stages before them and its outputs' unwritten zeros."""

    local_sizes: tuple[int, ...]
    prologue: ca.Function  # the kernel's inputs -> one column per prologue write
    prologue_writes: tuple[Slice, ...]
    loops: tuple[Loop, ...]
    unwritten: tuple[tuple[int, tuple[int, ...]], ...]  # (output, elements nothing writes: 0)
    stages: tuple[Stage, ...] = ()  # run before the prologue, in order

    def executed(self) -> list[tuple[ca.Function, int]]:
        """(function, times it runs per call): the prologue once, each loop body per iteration (stages not included)."""
        return [(self.prologue, 1)] + [(loop.body, len(loop.iterations())) for loop in self.loops]


@dataclass(frozen=True)
class _StageValues:
    """A stage as the builder holds it: the symbols its locals hold until outputs() puts the
    values in their place."""

    name: str
    names: list[str]
    values: list[ca.SX]
    symbols: list[ca.SX]
    arrays: list[int]


WRITTEN = "written by a loop"  # what an element holds once a loop writes it, until outputs()


@dataclass
class ScheduleBuilder:
    """Collects a schedule: the prologue's and stages' SX values, and the loops, each checked
    against what the loops before it wrote."""

    inputs: list[ca.SX]
    output_sizes: list[int]
    # each element: its SX value from the prologue or a stage, WRITTEN, or None (unwritten)
    _locals: list[list] = field(default_factory=list)
    _outputs: list[list] = field(default_factory=list)
    _prologue: list[tuple[ca.SX, Slice]] = field(default_factory=list)
    _loops: list[Loop] = field(default_factory=list)
    _stages: list[_StageValues] = field(default_factory=list)
    _flat: list[ca.SX] | None = None
    _input_elements: dict[int, list[ca.SX]] = field(default_factory=dict)  # an input port's, as loops read them

    def __post_init__(self):
        self._outputs = [[None] * size for size in self.output_sizes]

    def local(self, values: ca.SX | ca.DM | None = None, size: int | None = None) -> int:
        """A local array, filled by the prologue with ``values`` or left for loops to write."""
        if values is not None:
            size = values.numel()
        if size is None:
            raise TypeError("a local array needs its values or its size")
        self._locals.append([None] * size)
        index = len(self._locals) - 1
        if values is not None:
            self.prologue(Slice(LOCAL, index), ca.vec(values))
        return index

    def stage(self, name: str, outputs: list[tuple[str, ca.SX]]) -> list[int]:
        """Locals filled by the Stage ``name`` with the (output name, values of the kernel's
        inputs) ``outputs``. Until outputs() they hold symbols standing for the values, so
        that the loops read them as the helper's results (the prologue does not read them)."""
        standing, arrays = [], []
        for output, values in outputs:
            values = ca.vec(values)
            symbol = ca.SX.sym(f"{name}_{output}", values.numel())
            self._locals.append([symbol[e] for e in range(values.numel())])
            standing.append(symbol)
            arrays.append(len(self._locals) - 1)
        self._flat = None
        self._stages.append(
            _StageValues(name, [o for o, _ in outputs], [ca.vec(v) for _, v in outputs], standing, arrays)
        )
        return arrays

    def prologue(self, target: Slice, values: ca.SX) -> None:
        """``values`` (of the kernel's inputs only) into ``target`` before any loop runs. Called
        after loops, the target must be untouched so far: the write moves ahead of them."""
        values = ca.vec(values)
        if self._loops and any(v is not None for v in self._load_any(target, values.numel())):
            raise ValueError("a prologue write after loops must go to elements nothing wrote")
        self._store(target, [values[e] for e in range(values.numel())], 0, 0)
        self._prologue.append((values, target))
        self._flat = None

    def loop(
        self,
        body: ca.Function,
        space: str,
        n: int,
        reads: list[Slice],
        writes: list[Slice],
        pairs: Sequence[tuple[int, int]] = (),
    ) -> None:
        """Add a loop, checking that every element it reads was written before (an input's are)."""
        loop = Loop(body, space, n, tuple(reads), tuple(writes), tuple(pairs))
        if (space == PAIRS) != bool(pairs):
            raise ValueError("the space PAIRS, and it alone, lists its pairs")
        if any(s.kind == INPUT for s in writes):
            raise ValueError("loops do not write inputs")
        for i, j in loop.iterations():
            for k, s in enumerate(reads):
                self._load(s, body.size1_in(k), i, j)
            for k, s in enumerate(writes):
                self._store(s, [WRITTEN] * body.size1_out(k), i, j)
        self._loops.append(loop)
        self._flat = None

    def _array(self, s: Slice, arrays: tuple[list, list] | None = None) -> list:
        if s.kind == INPUT:
            if s.index not in self._input_elements:
                symbol = self.inputs[s.index]
                self._input_elements[s.index] = [symbol[e] for e in range(symbol.numel())]
            return self._input_elements[s.index]
        local, output = arrays or (self._locals, self._outputs)
        return local[s.index] if s.kind == LOCAL else output[s.index]

    def _load(self, s: Slice, count: int, i: int, j: int, arrays: tuple[list, list] | None = None) -> list:
        array = self._array(s, arrays)
        values = [array[e] for e in s.elements(count, i, j)]
        if any(v is None for v in values):
            raise ValueError(f"a loop reads local {s.index} before it is written")
        return values

    def _load_any(self, s: Slice, count: int) -> list:
        array = self._array(s)
        return [array[e] for e in s.elements(count, 0, 0)]

    def _store(self, s: Slice, values: list, i: int, j: int, arrays: tuple[list, list] | None = None) -> None:
        array = self._array(s, arrays)
        for e, v in zip(s.elements(len(values), i, j), values):
            array[e] = v

    def outputs(self) -> list[ca.SX]:
        """The kernel's outputs as SX columns (elements nothing writes are 0), of its inputs
        alone (the stages' values in place of their symbols): the loops applied in order to
        what the prologue and stages wrote."""
        if self._flat is None:
            self._flat = self._flatten()
        return self._flat

    def _flatten(self) -> list[ca.SX]:
        """The stages' symbols and the prologue's values (which only go to elements no loop
        wrote before them), then the loops in order."""
        arrays: tuple[list[list[ca.SX | None]], list[list[ca.SX | None]]] = (
            [[None] * len(a) for a in self._locals],
            [[None] * size for size in self.output_sizes],
        )
        for st in self._stages:
            for symbol, index in zip(st.symbols, st.arrays):
                arrays[0][index] = [symbol[e] for e in range(symbol.numel())]
        for values, target in self._prologue:
            self._store(target, [values[e] for e in range(values.numel())], 0, 0, arrays)
        for loop in self._loops:
            for i, j in loop.iterations():
                args = [
                    ca.vertcat(*self._load(s, loop.body.size1_in(k), i, j, arrays)) for k, s in enumerate(loop.reads)
                ]
                results = loop.body(*args)
                results = [results] if loop.body.n_out() == 1 else results
                for s, value in zip(loop.writes, results):
                    value = ca.densify(ca.vec(value))
                    self._store(s, [value[e] for e in range(value.numel())], i, j, arrays)
        columns = [ca.vertcat(*[ca.SX(0) if v is None else v for v in out]) for out in arrays[1]]
        if not self._stages:
            return columns
        return ca.substitute(
            columns, [s for st in self._stages for s in st.symbols], [v for st in self._stages for v in st.values]
        )

    def finish(self, inputs: list[ca.SX] | None = None) -> Schedule:
        """``inputs``: the kernel's input symbols if they differ from the builder's (a run-time
        parameter port added)."""
        inputs = inputs or self.inputs
        stages = []
        for st in self._stages:
            read = tuple(k for k, x in enumerate(inputs) if any(ca.depends_on(v, x) for v in st.values))
            function = ca.Function(st.name, [inputs[k] for k in read], st.values, {"cse": True})
            stages.append(Stage(st.name, function, read, tuple(st.arrays), tuple(st.names)))
        prologue = ca.Function("prologue", inputs, [v for v, _ in self._prologue], {"cse": True})
        unwritten = tuple(
            (k, tuple(e for e, v in enumerate(out) if v is None))
            for k, out in enumerate(self._outputs)
            if any(v is None for v in out)
        )
        return Schedule(
            tuple(len(a) for a in self._locals),
            prologue,
            tuple(s for _, s in self._prologue),
            tuple(self._loops),
            unwritten,
            tuple(stages),
        )


def body(name: str, inputs: list[ca.SX], outputs: list[ca.SX]) -> ca.Function:
    """A loop body: SX columns in, dense columns out."""
    return ca.Function(name, inputs, [ca.densify(ca.vec(o)) for o in outputs], {"cse": True})


def symbols(names: str, size: int = 6) -> list[ca.SX]:
    """Columns of ``size`` symbols, one per space-separated name (a body's inputs)."""
    return [ca.SX.sym(name, size) for name in names.split()]


def block(array: int, width: int, by: str = "i", offset: int = 0) -> Slice:
    """Block i (or j, ``by``) of ``width`` elements of a local array, from ``offset``."""
    return Slice(LOCAL, array, offset, i_stride=width if by == "i" else 0, j_stride=width if by == "j" else 0)
