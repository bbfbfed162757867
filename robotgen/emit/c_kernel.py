"""Prints one kernel's SX program as a C99 function.

Signature: ``int <prefix>_<kernel>(const real *<in>..., real *<out>...)``, returning 0.
Every pointer is required (never NULL) and must hold its port's size; outputs must not
overlap inputs, because inputs are read while outputs are being written. The body uses
only local scalars ``w0, w1, ...`` (CasADi's work registers): no statics, no heap, no I/O.

A kernel's run-time parameter port (``Port.parameters``, robotgen.symbolic.kernel.PARAMS)
is ``const <prefix>_params *params`` instead: element k of the port is read as the field
(or field element) that holds element k of the parameters' values concatenated.
"""

from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robotgen.emit import lane_names, passes, sincos
from robotgen.emit.passes import Use
from robotgen.emit.sx_program import Instruction, KernelError, Program, read_program, reads_first
from robotgen.symbolic.kernel import PARAMS, Kernel, Port
from robotgen.symbolic.schedule import (
    ABOVE,
    ABOVE_DESCENDING,
    BELOW,
    DESCENDING,
    INPUT,
    LOCAL,
    ONCE,
    OUTPUT,
    PAIRS,
    RANGE,
    Slice,
    Stage,
)


@dataclass(frozen=True)
class Precision:
    """A C floating type the kernels are printed in: its name, the C type, and the suffixes of its literals and
    <math.h> functions."""

    name: str
    real: str  # C type
    literal_suffix: str  # on floating constants
    math_suffix: str  # on <math.h> function names: sin -> sinf


PRECISIONS = {
    "double": Precision("double", "double", "", ""),
    "float": Precision("float", "float", "f", "f"),
}

# C spelling of every scalar operation: (operand count, pattern). {0}/{1}: operand
# registers; {one}/{zero}: literals of the kernel's precision; {fs}: the <math.h> suffix.
_OPERATORS = {
    "OP_ASSIGN": (1, "{0}"),
    "OP_ADD": (2, "{0} + {1}"),
    "OP_SUB": (2, "{0} - {1}"),
    "OP_MUL": (2, "{0} * {1}"),
    "OP_DIV": (2, "{0} / {1}"),
    "OP_NEG": (1, "-{0}"),
    "OP_SQ": (1, "{0} * {0}"),
    "OP_TWICE": (1, "{0} + {0}"),
    "OP_INV": (1, "{one} / {0}"),
    "OP_SIGN": (1, "{0} < {zero} ? -{one} : {0} > {zero} ? {one} : {0}"),
    "OP_IF_ELSE_ZERO": (2, "{0} ? {1} : {zero}"),
    "OP_LT": (2, "{0} < {1}"),
    "OP_LE": (2, "{0} <= {1}"),
    "OP_EQ": (2, "{0} == {1}"),
    "OP_NE": (2, "{0} != {1}"),
    "OP_NOT": (1, "!{0}"),
    "OP_AND": (2, "{0} && {1}"),
    "OP_OR": (2, "{0} || {1}"),
}
_UNARY_CALLS = {
    "OP_SQRT": "sqrt",
    "OP_EXP": "exp",
    "OP_LOG": "log",
    "OP_SIN": "sin",
    "OP_COS": "cos",
    "OP_TAN": "tan",
    "OP_ASIN": "asin",
    "OP_ACOS": "acos",
    "OP_ATAN": "atan",
    "OP_SINH": "sinh",
    "OP_COSH": "cosh",
    "OP_TANH": "tanh",
    "OP_ASINH": "asinh",
    "OP_ACOSH": "acosh",
    "OP_ATANH": "atanh",
    "OP_FABS": "fabs",
    "OP_FLOOR": "floor",
    "OP_CEIL": "ceil",
    "OP_ERF": "erf",
    "OP_LOG1P": "log1p",
    "OP_EXPM1": "expm1",
}
_BINARY_CALLS = {
    "OP_POW": "pow",
    "OP_CONSTPOW": "pow",
    "OP_ATAN2": "atan2",
    "OP_COPYSIGN": "copysign",
    "OP_FMIN": "fmin",
    "OP_FMAX": "fmax",
    "OP_FMOD": "fmod",
    "OP_REMAINDER": "remainder",
    "OP_HYPOT": "hypot",
}
_MATH_FUNCTIONS = frozenset(_UNARY_CALLS.values()) | frozenset(_BINARY_CALLS.values())

# casadi op code -> (operand count, C pattern), for the ops this casadi version has.
OPERATIONS: dict[int, tuple[int, str]] = {
    getattr(ca, op): spelling
    for op, spelling in [
        *_OPERATORS.items(),
        *((op, (1, fn + "{fs}({0})")) for op, fn in _UNARY_CALLS.items()),
        *((op, (2, fn + "{fs}({0}, {1})")) for op, fn in _BINARY_CALLS.items()),
    ]
    if hasattr(ca, op)
}

C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto "
    "if inline int long register restrict return short signed sizeof static struct switch "
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary".split()
)
RESERVED = C_KEYWORDS | _MATH_FUNCTIONS | {f + "f" for f in _MATH_FUNCTIONS} | {"INFINITY", "NAN"}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_REGISTER = re.compile(r"[wxt][0-9]+\Z")


def check_identifier(name: str, what: str) -> None:
    """``name`` must be usable as a C identifier and a Python attribute."""
    if not _IDENTIFIER.match(name) or name in C_KEYWORDS or keyword.iskeyword(name):
        raise KernelError(f"{what} {name!r} is not a valid C and Python identifier")


def function_name(prefix: str, kernel: Kernel) -> str:
    """The C name of a kernel in a module: <prefix>_<kernel name>."""
    return f"{prefix}_{kernel.name}"


def is_parameter_port(port: Port) -> bool:
    """Whether ``port`` carries the module's run-time parameters (a struct, not an array)."""
    return port.name == PARAMS and bool(port.parameters)


def params_type(prefix: str) -> str:
    """The C struct of a module's run-time parameters."""
    return f"{prefix}_params"


def parameter_elements(port: Port) -> list[str]:
    """The C expression reading each element of a parameter port, in port order."""
    elements = []
    for parameter in port.parameters:
        if parameter.shape:
            elements += [f"{port.name}->{parameter.name}[{j}]" for j in range(parameter.size)]
        else:
            elements.append(f"{port.name}->{parameter.name}")
    return elements


def prototype(prefix: str, kernel: Kernel, precision: Precision) -> str:
    """A kernel's C prototype: its inputs as const pointers (the parameter struct for a params port), then its
    outputs."""
    params = [
        f"const {params_type(prefix)} *{p.name}" if is_parameter_port(p) else f"const {precision.real} *{p.name}"
        for p in kernel.inputs
    ]
    params += [f"{precision.real} *{p.name}" for p in kernel.outputs]
    return f"int {function_name(prefix, kernel)}({', '.join(params) or 'void'})"


def kernel_source(
    prefix: str,
    kernel: Kernel,
    precision: Precision,
    program: Program | None = None,
    helpers: dict[Stage, str] | None = None,
) -> str:
    """The C definition of ``kernel``; ``program`` may be passed if already read. ``helpers``:
    the C name of each of its schedule's stages (stage_source), by default rg_<stage>."""
    declarations, body, named = _body(kernel, precision, program, helpers, lanes=False)
    lines = [prototype(prefix, kernel, precision) + " {", *("  " + d for d in declarations)]
    lines += _unused(kernel, named)
    if kernel.guarded:
        lines += _guard_inputs(kernel)
    lines += _guard_step(kernel, precision)
    lines += ["  " + line for line in body]
    lines += _guard_outputs(kernel, precision) if kernel.guarded else ["  return 0;"]
    lines += ["}"]
    return "\n".join(lines) + "\n"


LANE_KERNEL = "rgl_"  # a kernel's lane form: static, rgl_<kernel> per width


def lane_kernel_source(
    prefix: str,
    kernel: Kernel,
    precision: Precision,
    program: Program | None = None,
    helpers: dict[Stage, str] | None = None,
) -> str:
    """``kernel``'s lane form (robotgen.emit.lanes): the statements of kernel_source in the same
    order on vectors of W states, its ports arrays of vectors (one state per lane, a port's
    element k in vector k), the parameters read from the struct into every lane. It has no
    guards: the batch driver checks each state as the single-state function does."""
    declarations, body, named = _body(kernel, precision, program, helpers, lanes=True)
    params = [
        f"const {params_type(prefix)} *{p.name}" if is_parameter_port(p) else f"const {lane_names.VECTOR} *{p.name}"
        for p in kernel.inputs
    ]
    params += [f"{lane_names.VECTOR} *{p.name}" for p in kernel.outputs]
    lines = [
        f"static {lane_names.TARGET} void {lane_names.per_width(LANE_KERNEL + kernel.name)}({', '.join(params)}) {{",
        *("  " + d for d in declarations),
    ]
    lines += _unused(kernel, named)
    lines += ["  " + line for line in body]
    return "\n".join([*lines, "}"]) + "\n"


def _body(
    kernel: Kernel,
    precision: Precision,
    program: Program | None,
    helpers: dict[Stage, str] | None,
    lanes: bool,
) -> tuple[list[str], list[str], NamedPorts]:
    """(declarations, statements, the ports named) of kernel_source's body, or with ``lanes``
    of lane_kernel_source's: the same statements, parameters broadcast, stage helpers the
    width's copies."""
    _check_ports(kernel)
    fields = {i: parameter_elements(p) for i, p in enumerate(kernel.inputs) if is_parameter_port(p)}

    def read(port: int, element: int) -> str:
        if port in fields:
            return lane_names.splat(fields[port][element]) if lanes else fields[port][element]
        return f"{kernel.inputs[port].name}[{element}]"

    if kernel.schedule is not None:
        names = helpers or {stage: stage_name(stage) for stage in kernel.schedule.stages}
        if lanes:
            names = {stage: lane_names.per_width(name) for stage, name in names.items()}
        return _scheduled_body(kernel, precision, read, names, lanes=lanes)
    program = program or read_program(kernel)
    declarations, statements = _straight_line(
        _block(program),
        kernel,
        precision,
        read,
        lambda port, element: (kernel.outputs[port].name, element),
        lanes=lanes,
    )
    zero = _literal(0.0, precision, lanes)
    for port_index, elements in program.unwritten_outputs:
        name = kernel.outputs[port_index].name
        statements += [Store(name, e, zero) for e in elements]
    return declarations, [str(statement) for statement in statements], _named_ports(program)


@dataclass(frozen=True)
class NamedPorts:
    """The ports of a kernel its C names (by index): the inputs it reads, the outputs it writes."""

    inputs: frozenset[int]
    outputs: frozenset[int]


def _named_ports(program: Program) -> NamedPorts:
    """The ports a straight-line program's C names: those it reads, writes or zeroes."""
    return NamedPorts(
        frozenset(s.port for s in program.instructions if s.op == ca.OP_INPUT),
        frozenset(s.port for s in program.instructions if s.op == ca.OP_OUTPUT)
        | frozenset(port for port, elements in program.unwritten_outputs if elements),
    )


def _unused(kernel: Kernel, named: NamedPorts) -> list[str]:
    """A (void) cast of each port the kernel's C does not name, so that compilers do not warn of it."""
    return [f"  (void){p.name};" for k, p in enumerate(kernel.inputs) if k not in named.inputs] + [
        f"  (void){p.name};" for k, p in enumerate(kernel.outputs) if k not in named.outputs
    ]


def _straight_line(
    program: Program, kernel: Kernel, precision: Precision, read, write, register: str = "w", lanes: bool = False
) -> tuple[list[str], list[str | Store]]:
    """(declarations of the registers, statements) of one SX program, printed as it is (its
    passes applied before: robotgen.emit.passes); ``read(port, element)`` spells an input,
    ``write(port, element)`` an output's element: (array, index) or, at an index that is not a
    constant, its text; ``register`` names the registers. A store at a constant index is a
    Store (for fills)."""
    body: list[str | Store] = []
    for step in program.instructions:
        if step.op == sincos.SINCOS:
            body += _sincos_statements(step, register, precision, lanes)
        else:
            body.append(_statement(step, kernel, precision, read, write, register, lanes))
    registers = sorted({s.target for s in program.instructions if s.target >= 0})
    real = lane_names.VECTOR if lanes else precision.real
    declarations = [
        f"{real} " + ", ".join(f"{register}{r}" for r in registers[start : start + 12]) + ";"
        for start in range(0, len(registers), 12)
    ]
    if sincos.uses_helper(program):
        n = sincos.lanes(program)
        declarations.append(f"{real} {sincos.ANGLES}[{n}], {sincos.SINES}[{n}], {sincos.COSINES}[{n}];")
    if lanes and any(lane_names.LANE_INDEX + "]" in line for line in body if isinstance(line, str)):
        declarations.append(f"int {lane_names.LANE_INDEX};")
    return declarations, body


def _block(program: Program) -> Program:
    """A straight-line block's program (a kernel's, a stage helper's, a prologue's) after the passes chosen for it."""
    return passes.choose(program, Use.BLOCK).apply(program)


def _sincos_statements(step: Instruction, register: str, precision: Precision, lanes: bool = False) -> list[str]:
    """The angles into their lanes (an odd one paired with 0), then sin and cos two at a time
    (with ``lanes``, every angle of W states in one call, each lane as the pairs give it)."""
    angles = [f"{register}{r}" for r in step.args]
    arrays = f"{sincos.ANGLES}, {sincos.SINES}, {sincos.COSINES}"
    if lanes:
        return [f"{sincos.ANGLES}[{lane}] = {angle};" for lane, angle in enumerate(angles)] + [
            f"{lane_names.per_width(sincos.LANE_HELPER)}({len(angles)}, {arrays});"
        ]
    if len(angles) % 2:
        angles.append(literal(0.0, precision))
    lines = [f"{sincos.ANGLES}[{lane}] = {angle};" for lane, angle in enumerate(angles)]
    for lane in range(0, len(angles), 2):
        offset = f" + {lane}" if lane else ""
        lines.append(f"{sincos.HELPER}({sincos.ANGLES}{offset}, {sincos.SINES}{offset}, {sincos.COSINES}{offset});")
    return lines


LOOP_INDICES = ("rg_i", "rg_j", "rg_m")  # a schedule's loop counters (no port or register is named so)
_LOOP_HEADERS = {
    ONCE: ["{{"],
    RANGE: ["for (rg_i = 0; rg_i < {n}; ++rg_i) {{"],
    DESCENDING: ["for (rg_i = {n} - 1; rg_i >= 0; --rg_i) {{"],
    BELOW: ["for (rg_j = 0; rg_j < {n}; ++rg_j)", "  for (rg_i = rg_j + 1; rg_i < {n}; ++rg_i) {{"],
    ABOVE: ["for (rg_j = 1; rg_j < {n}; ++rg_j)", "  for (rg_i = 0; rg_i < rg_j; ++rg_i) {{"],
    ABOVE_DESCENDING: ["for (rg_j = {n} - 1; rg_j > 0; --rg_j)", "  for (rg_i = 0; rg_i < rg_j; ++rg_i) {{"],
}


def stage_name(stage: Stage) -> str:
    """A stage's helper is static: named like rg_sincos2, without the module's prefix."""
    return f"rg_{stage.name}"


def stage_source(c_name: str, stage: Stage, kernel: Kernel, precision: Precision, lanes: bool = False) -> str:
    """The static helper that does ``stage`` of ``kernel``'s schedule: its parameters are the
    kernel's inputs that the stage reads, then one array per output. With ``lanes``, its lane
    form (robotgen.emit.lanes): arrays of vectors, named per width."""
    ports = tuple(kernel.inputs[k] for k in stage.inputs)
    names = [p.name for p in ports] + list(stage.names)
    if any(is_parameter_port(p) for p in ports) or len(set(names)) != len(names):
        raise KernelError(
            f"kernel {kernel.name!r}: stage {stage.name!r} reads a parameter port or its names repeat: {names}"
        )
    inner = part_kernel(stage.name, stage.function, ports)
    program = read_program(inner)
    registers, statements = _straight_line(
        _block(program),
        inner,
        precision,
        lambda port, e: f"{ports[port].name}[{e}]",
        lambda port, e: (stage.names[port], e),
        lanes=lanes,
    )
    zero = _literal(0.0, precision, lanes)
    statements += [Store(stage.names[port], e, zero) for port, elements in program.unwritten_outputs for e in elements]
    lines = fills(statements)
    real = lane_names.VECTOR if lanes else precision.real
    parameters = [f"const {real} *{p.name}" for p in ports] + [f"{real} *{n}" for n in stage.names]
    head = f"static {lane_names.TARGET} void {lane_names.per_width(c_name)}" if lanes else f"static void {c_name}"
    return "\n".join([f"{head}({', '.join(parameters)}) {{", *("  " + line for line in registers + lines), "}"]) + "\n"


def _scheduled_body(
    kernel: Kernel, precision: Precision, read, helpers: dict[Stage, str], lanes: bool = False
) -> tuple[list[str], list[str], NamedPorts]:
    """A schedule's C: local arrays t0, t1, ...; a call of each stage's helper; the prologue
    as one straight-line block; each loop as a block whose body reads and writes slices
    (registers x0, x1, ...). With ``lanes``, every local and register is a vector of states.
    Also the kernel's ports it names: the stages' and the prologue's inputs, the outputs that
    the prologue and the loops write into and that are zeroed."""
    schedule = kernel.schedule
    assert schedule is not None  # a scheduled kernel's
    zero = _literal(0.0, precision, lanes)
    real = lane_names.VECTOR if lanes else precision.real
    declarations = [f"{real} t{k}[{size}];" for k, size in enumerate(schedule.local_sizes)]
    # index tables (a tree's parents, its ancestor pairs): const locals rg_p0, rg_p1, ...
    tables: dict[tuple[int, ...], str] = {}

    def table(values: tuple[int, ...]) -> str:
        if values not in tables:
            tables[values] = f"rg_p{len(tables)}"
        return tables[values]

    if schedule.loops:
        pairs = any(loop.space not in (ONCE, RANGE, DESCENDING) for loop in schedule.loops)
        listed = any(loop.space == PAIRS for loop in schedule.loops)
        used = LOOP_INDICES if listed else LOOP_INDICES[:2] if pairs else LOOP_INDICES[:1]
        declarations.append("int " + ", ".join(used) + ";")

    def array(s: Slice) -> str:
        if s.kind == INPUT:
            return kernel.inputs[s.index].name
        return f"t{s.index}" if s.kind == LOCAL else kernel.outputs[s.index].name

    def target(s: Slice, element: int) -> tuple[str, int] | str:
        """Where an element of slice ``s`` is written: (array, index) when the index is a constant."""
        return address(s, element) if s.i_stride or s.j_stride else (array(s), s.offset + element * s.step)

    def address(s: Slice, element: int) -> str:
        start = s.offset + element * s.step
        i = f"{table(s.i_table)}[rg_i]" if s.i_table else "rg_i"
        terms = [str(start)] if start or not (s.i_stride or s.j_stride) else []
        terms += [
            f"{stride} * {index}" if stride != 1 else index
            for stride, index in ((s.i_stride, i), (s.j_stride, "rg_j"))
            if stride
        ]
        return f"{array(s)}[{' + '.join(terms)}]"

    body = []
    for stage in schedule.stages:
        arguments = [kernel.inputs[k].name for k in stage.inputs] + [f"t{a}" for a in stage.writes]
        body.append(f"{helpers[stage]}({', '.join(arguments)});")
    prologue = part_kernel(kernel.name + "_prologue", schedule.prologue, kernel.inputs)
    program = read_program(prologue)
    writes = schedule.prologue_writes
    named = _named_ports(program)
    inputs = {k for stage in schedule.stages for k in stage.inputs} | named.inputs
    outputs = {writes[port].index for port in named.outputs if writes[port].kind != LOCAL}
    registers, statements = _straight_line(
        _block(program),
        prologue,
        precision,
        read,
        lambda port, element: target(writes[port], element),
        lanes=lanes,
    )
    statements += [
        _store(target(writes[port], e), zero) for port, elements in program.unwritten_outputs for e in elements
    ]
    body += ["{", *("  " + line for line in registers + fills(statements)), "}"]
    for loop in schedule.loops:
        inner = part_kernel(kernel.name + "_" + loop.body.name(), loop.body)
        program = reads_first(read_program(inner))
        named = _named_ports(program)
        outputs |= {loop.writes[port].index for port in named.outputs if loop.writes[port].kind != LOCAL}
        outputs |= {loop.reads[port].index for port in named.inputs if loop.reads[port].kind == OUTPUT}
        inputs |= {loop.reads[port].index for port in named.inputs if loop.reads[port].kind == INPUT}
        registers, statements = _straight_line(
            passes.choose(program, Use.LOOP_BODY).apply(program),
            inner,
            precision,
            lambda port, element, loop=loop: address(loop.reads[port], element),
            lambda port, element, loop=loop: address(loop.writes[port], element),
            register="x",
            lanes=lanes,
        )
        statements += [
            f"{address(loop.writes[port], e)} = {zero};"
            for port, elements in program.unwritten_outputs
            for e in elements
        ]
        lines = [str(statement) for statement in statements]
        if loop.space == PAIRS:
            first, second = table(tuple(i for i, _ in loop.pairs)), table(tuple(j for _, j in loop.pairs))
            body += [
                f"for (rg_m = 0; rg_m < {len(loop.pairs)}; ++rg_m) {{",
                f"  rg_i = {first}[rg_m];",
                f"  rg_j = {second}[rg_m];",
                "  {",
                *("    " + line for line in registers + lines),
                "  }",
                "}",
            ]
            continue
        header = [line.format(n=loop.n) for line in _LOOP_HEADERS[loop.space]]
        body += [*header, *("    " + line for line in registers + lines), "  }" if len(header) > 1 else "}"]
    for port, elements in schedule.unwritten:
        body += fills([Store(kernel.outputs[port].name, e, zero) for e in elements])
        outputs |= {port} if elements else set()
    declarations += [
        f"const int {name}[{len(values)}] = {{{', '.join(map(str, values))}}};" for values, name in tables.items()
    ]
    return declarations, body, NamedPorts(frozenset(inputs), frozenset(outputs))


# A run of at least FILL_RUN statements storing one value into consecutive elements of an array
# is printed as a loop. A schedule's prologue zeroes the arrays its loops add into and the
# outputs they leave alone, up to a thousand stores in a row on a large tree, and gcc's
# dead-store and alias passes take time quadratic in such a block. Shorter runs stay stores:
# as loops they made a mass matrix slower (docs/performance-log.md). The loop stores two
# elements per step (an odd run's last store follows it): gcc -O2 makes that one 16-byte store
# per step, where a loop of single stores of zero became `rep stosq` (an inline memset, slow to
# start) and of another value stayed scalar.
FILL_RUN = 64


@dataclass(frozen=True)
class Store:
    """A statement storing ``value`` (a register or a literal) into ``array[index]``, the index a constant."""

    array: str
    index: int
    value: str

    def __str__(self) -> str:
        return f"{self.array}[{self.index}] = {self.value};"


def _store(where: tuple[str, int] | str, value: str) -> str | Store:
    """The store of ``value`` at ``where``: (array, index) or an address's text."""
    return Store(where[0], where[1], value) if isinstance(where, tuple) else f"{where} = {value};"


def fills(statements: list[str | Store]) -> list[str]:
    """The statements as text, every run of FILL_RUN or more Stores of one value into consecutive elements as a loop."""
    out: list[str] = []
    k = 0
    while k < len(statements):
        first = statements[k]
        end = k + 1
        if isinstance(first, Store):
            following = Store(first.array, first.index + 1, first.value)
            while end < len(statements) and statements[end] == following:
                following = Store(first.array, following.index + 1, first.value)
                end += 1
        if isinstance(first, Store) and end - k >= FILL_RUN:
            even = (end - k) // 2 * 2
            array, value = first.array, first.value
            out.append(
                f"for (int rg_e = {first.index}; rg_e < {first.index + even}; rg_e += 2) "
                f"{{ {array}[rg_e] = {value}; {array}[rg_e + 1] = {value}; }}"
            )
            out += map(str, statements[k + even : end])
        else:
            out += map(str, statements[k:end])
        k = end
    return out


def part_kernel(name: str, function: ca.Function, inputs: tuple[Port, ...] | None = None) -> Kernel:
    """A schedule's prologue or loop body as a kernel, for read_program."""
    if inputs is None:
        inputs = tuple(Port(f"in{k}", function.size1_in(k)) for k in range(function.n_in()))
    outputs = tuple(Port(f"out{k}", function.size1_out(k)) for k in range(function.n_out()))
    return Kernel(name, "", inputs, outputs, function)


GUARD_INDEX = "rg_k"  # the guards' loop counter (no port or register is named so)
GUARD_SUM = "rg_g"  # the output guard's partial sums rg_g0, rg_g1, ...


def _guard_inputs(kernel: Kernel) -> list[str]:
    """Status 1 before anything is written when an input (not a parameter) is NaN or Inf."""
    lines = [f"  int {GUARD_INDEX};"]
    for port in kernel.inputs:
        if not is_parameter_port(port):
            lines.append(
                f"  for ({GUARD_INDEX} = 0; {GUARD_INDEX} < {port.size}; ++{GUARD_INDEX}) "
                f"if (!isfinite({port.name}[{GUARD_INDEX}])) return 1;"
            )
    return lines


STEP_PORT = "dt"  # a step length: a kernel taking one refuses dt <= 0 (status 3)
EXIT_BAD_STEP = 3


def _guard_step(kernel: Kernel, precision: Precision) -> list[str]:
    """Status 3 before anything is written when the step dt is not positive (a checked
    kernel has already returned 1 for a NaN dt)."""
    return [
        f"  if ({STEP_PORT}[0] <= {literal(0.0, precision)}) return {EXIT_BAD_STEP};"
        for port in kernel.inputs
        if port.name == STEP_PORT and port.size == 1
    ]


def _guard_outputs(kernel: Kernel, precision: Precision) -> list[str]:
    """Status 2 with every output zeroed when a result is not finite: no NaN leaves.

    x - x is 0 for a finite x and NaN for a NaN or an infinity, so a sum of those is 0 exactly
    when every element is finite: summed as balanced trees (in groups of 8, then the groups),
    the check is independent operations and one branch, not a branch per element."""
    zero = literal(0.0, precision)
    elements = [f"{p.name}[{k}]" for p in kernel.outputs for k in range(p.size)]
    groups = [elements[start : start + 8] for start in range(0, len(elements), 8)]
    lines = [
        f"  {precision.real} " + ", ".join(f"{GUARD_SUM}{g}" for g in range(start, min(start + 12, len(groups)))) + ";"
        for start in range(0, len(groups), 12)
    ]
    lines += [f"  {GUARD_SUM}{g} = {_balanced([f'({e} - {e})' for e in group])};" for g, group in enumerate(groups)]
    lines.append(f"  if ({_balanced([f'{GUARD_SUM}{g}' for g in range(len(groups))])} != {zero}) goto not_finite;")
    # one store per element: a loop of stores would be compiled into a call of memset, which a
    # freestanding (microcontroller) build may not have
    clears = [f"  {p.name}[{k}] = {zero};" for p in kernel.outputs for k in range(p.size)]
    return [*lines, "  return 0;", "not_finite:", *clears, "  return 2;"]


def _balanced(terms: list[str]) -> str:
    """``terms`` summed as a balanced tree of parenthesised pairs."""
    while len(terms) > 1:
        pairs = [f"({terms[k]} + {terms[k + 1]})" for k in range(0, len(terms) - 1, 2)]
        terms = pairs + terms[len(terms) - len(terms) % 2 :]
    return terms[0]


def _check_ports(kernel: Kernel) -> None:
    names = [p.name for p in (*kernel.inputs, *kernel.outputs)]
    for name in names:
        check_identifier(name, f"kernel {kernel.name!r}: port")
        if name in RESERVED or _REGISTER.match(name) or name.startswith("rg_"):
            raise KernelError(f"kernel {kernel.name!r}: port name {name!r} is reserved in C")
    if len(set(names)) != len(names):
        raise KernelError(f"kernel {kernel.name!r}: port names repeat: {names}")


# Operations printed on whole vectors in a lane kernel; any other is printed lane by lane, as the
# scalar statement on each lane (selections by sign, <math.h> calls), so that every lane computes
# what the single-state function computes.
_VECTOR_OPERATIONS = frozenset(
    getattr(ca, op)
    for op in ("OP_ASSIGN", "OP_ADD", "OP_SUB", "OP_MUL", "OP_DIV", "OP_NEG", "OP_SQ", "OP_TWICE", "OP_INV")
)
# Comparisons, logic and the selection of CasADi's if_else on whole vectors, through masks: a
# comparison of two vectors gives all ones or zero per lane ({m}), and its bits and 1.0's give
# the 1.0 or 0.0 that C's scalar comparison gives; a condition is true where it is not 0 (NaN
# too, as in C). fabs clears the sign bit, as <math.h>'s does.
_MASKED_OPERATIONS = {
    getattr(ca, op): pattern
    for op, pattern in {
        "OP_LT": "({v})(({m})({0} < {1}) & ({m}){one})",
        "OP_LE": "({v})(({m})({0} <= {1}) & ({m}){one})",
        "OP_EQ": "({v})(({m})({0} == {1}) & ({m}){one})",
        "OP_NE": "({v})(({m})({0} != {1}) & ({m}){one})",
        "OP_NOT": "({v})(({m})({0} == {zero}) & ({m}){one})",
        "OP_AND": "({v})(({m})({0} != {zero}) & ({m})({1} != {zero}) & ({m}){one})",
        "OP_OR": "({v})((({m})({0} != {zero}) | ({m})({1} != {zero})) & ({m}){one})",
        "OP_IF_ELSE_ZERO": "({v})(({m})({0} != {zero}) & ({m}){1})",
        "OP_FABS": "({v})(({m}){0} & ~({m}){minus_zero})",
    }.items()
}


def _statement(
    step: Instruction, kernel: Kernel, precision: Precision, read, write, register: str, lanes: bool = False
) -> str | Store:
    if step.op in (sincos.SIN_LANE, sincos.COS_LANE):
        lanes_array = sincos.SINES if step.op == sincos.SIN_LANE else sincos.COSINES
        return f"{register}{step.target} = {lanes_array}[{step.element}];"
    if step.op == ca.OP_INPUT:
        return f"{register}{step.target} = {read(step.port, step.element)};"
    if step.op == ca.OP_OUTPUT:
        return _store(write(step.port, step.element), f"{register}{step.args[0]}")
    if step.op == ca.OP_CONST:
        return f"{register}{step.target} = {_literal(step.constant, precision, lanes)};"
    if step.op not in OPERATIONS:
        raise KernelError(f"kernel {kernel.name!r}: CasADi operation {step.op_name} has no C translation")
    arity, pattern = OPERATIONS[step.op]
    if len(step.args) != arity:
        raise KernelError(f"kernel {kernel.name!r}: {step.op_name} with {len(step.args)} operands, expected {arity}")
    if lanes and step.op in _MASKED_OPERATIONS:
        pattern = _MASKED_OPERATIONS[step.op]
    whole = lanes and (step.op in _VECTOR_OPERATIONS or step.op in _MASKED_OPERATIONS)
    lane = f"[{lane_names.LANE_INDEX}]" if lanes and not whole else ""
    expression = pattern.format(
        *(f"{register}{r}{lane}" for r in step.args),
        fs=precision.math_suffix,
        one=_literal(1.0, precision, whole),
        zero=_literal(0.0, precision, whole),
        minus_zero=_literal(-0.0, precision, whole),
        v=lane_names.VECTOR,
        m=lane_names.MASK_VECTOR,
    )
    if lane:
        index = lane_names.LANE_INDEX
        return (
            f"for ({index} = 0; {index} < {lane_names.WIDTH}; ++{index}) {register}{step.target}{lane} = {expression};"
        )
    return f"{register}{step.target} = {expression};"


def _literal(value: float, precision: Precision, lanes: bool) -> str:
    """A literal, in every lane with ``lanes``."""
    return lane_names.splat(literal(value, precision)) if lanes else literal(value, precision)


def literal(value: float, precision: Precision) -> str:
    """A C literal that reads back as exactly ``value`` (rounded to float for float)."""
    if precision.real == "float":
        with np.errstate(over="ignore"):
            value = float(np.float32(value))
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "-INFINITY"
    if precision.real == "float":
        text = next(
            t for t in (f"{value:.{digits}g}" for digits in range(1, 10)) if float(np.float32(float(t))) == value
        )
        text += "" if any(c in text for c in ".e") else ".0"
    else:
        text = repr(value)
    return text + precision.literal_suffix
