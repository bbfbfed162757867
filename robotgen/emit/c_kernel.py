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

from robotgen.emit.sx_program import Instruction, KernelError, Program, read_program
from robotgen.symbolic.kernel import PARAMS, Kernel, Port


@dataclass(frozen=True)
class Precision:
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
    "OP_SQRT": "sqrt", "OP_EXP": "exp", "OP_LOG": "log", "OP_SIN": "sin", "OP_COS": "cos",
    "OP_TAN": "tan", "OP_ASIN": "asin", "OP_ACOS": "acos", "OP_ATAN": "atan",
    "OP_SINH": "sinh", "OP_COSH": "cosh", "OP_TANH": "tanh", "OP_ASINH": "asinh",
    "OP_ACOSH": "acosh", "OP_ATANH": "atanh", "OP_FABS": "fabs", "OP_FLOOR": "floor",
    "OP_CEIL": "ceil", "OP_ERF": "erf", "OP_LOG1P": "log1p", "OP_EXPM1": "expm1",
}
_BINARY_CALLS = {
    "OP_POW": "pow", "OP_CONSTPOW": "pow", "OP_ATAN2": "atan2", "OP_COPYSIGN": "copysign",
    "OP_FMIN": "fmin", "OP_FMAX": "fmax", "OP_FMOD": "fmod", "OP_REMAINDER": "remainder",
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
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary".split())
RESERVED = (C_KEYWORDS | _MATH_FUNCTIONS | {f + "f" for f in _MATH_FUNCTIONS}
            | {"INFINITY", "NAN"})
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_REGISTER = re.compile(r"w[0-9]+\Z")


def check_identifier(name: str, what: str) -> None:
    """``name`` must be usable as a C identifier and a Python attribute."""
    if not _IDENTIFIER.match(name) or name in C_KEYWORDS or keyword.iskeyword(name):
        raise KernelError(f"{what} {name!r} is not a valid C and Python identifier")


def function_name(prefix: str, kernel: Kernel) -> str:
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
    params = [f"const {params_type(prefix)} *{p.name}" if is_parameter_port(p)
              else f"const {precision.real} *{p.name}" for p in kernel.inputs]
    params += [f"{precision.real} *{p.name}" for p in kernel.outputs]
    return f"int {function_name(prefix, kernel)}({', '.join(params) or 'void'})"


def kernel_source(prefix: str, kernel: Kernel, precision: Precision,
                  program: Program | None = None) -> str:
    """The C definition of ``kernel``; ``program`` may be passed if already read."""
    _check_ports(kernel)
    program = program or read_program(kernel)
    fields = {i: parameter_elements(p) for i, p in enumerate(kernel.inputs) if is_parameter_port(p)}
    body = [_statement(step, kernel, precision, fields) for step in program.instructions]
    zero = literal(0.0, precision)
    for port_index, elements in program.unwritten_outputs:
        name = kernel.outputs[port_index].name
        body += [f"{name}[{e}] = {zero};" for e in elements]
    used = {name for line in body for name in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", line)}
    registers = sorted({s.target for s in program.instructions if s.target >= 0})
    lines = [prototype(prefix, kernel, precision) + " {"]
    for start in range(0, len(registers), 12):
        chunk = registers[start:start + 12]
        lines.append(f"  {precision.real} " + ", ".join(f"w{r}" for r in chunk) + ";")
    lines += [f"  (void){p.name};" for p in (*kernel.inputs, *kernel.outputs)
              if p.name not in used]
    if kernel.guarded:
        lines += _guard_inputs(kernel)
    lines += ["  " + line for line in body]
    lines += _guard_outputs(kernel, precision) if kernel.guarded else ["  return 0;"]
    lines += ["}"]
    return "\n".join(lines) + "\n"


GUARD_INDEX = "rg_k"  # the guards' loop counter (no port or register is named so)


def _guard_inputs(kernel: Kernel) -> list[str]:
    """Status 1 before anything is written when an input (not a parameter) is NaN or Inf."""
    lines = [f"  int {GUARD_INDEX};"]
    for port in kernel.inputs:
        if not is_parameter_port(port):
            lines.append(f"  for ({GUARD_INDEX} = 0; {GUARD_INDEX} < {port.size}; ++{GUARD_INDEX}) "
                         f"if (!isfinite({port.name}[{GUARD_INDEX}])) return 1;")
    return lines


def _guard_outputs(kernel: Kernel, precision: Precision) -> list[str]:
    """Status 2 with every output zeroed when a result is not finite: no NaN leaves."""
    checks = [f"  for ({GUARD_INDEX} = 0; {GUARD_INDEX} < {p.size}; ++{GUARD_INDEX}) "
              f"if (!isfinite({p.name}[{GUARD_INDEX}])) goto not_finite;" for p in kernel.outputs]
    zero = literal(0.0, precision)
    # one store per element: a loop of stores would be compiled into a call of memset, which a
    # freestanding (microcontroller) build may not have
    clears = [f"  {p.name}[{k}] = {zero};" for p in kernel.outputs for k in range(p.size)]
    return [*checks, "  return 0;", "not_finite:", *clears, "  return 2;"]


def _check_ports(kernel: Kernel) -> None:
    names = [p.name for p in (*kernel.inputs, *kernel.outputs)]
    for name in names:
        check_identifier(name, f"kernel {kernel.name!r}: port")
        if name in RESERVED or _REGISTER.match(name) or name == GUARD_INDEX:
            raise KernelError(f"kernel {kernel.name!r}: port name {name!r} is reserved in C")
    if len(set(names)) != len(names):
        raise KernelError(f"kernel {kernel.name!r}: port names repeat: {names}")


def _statement(step: Instruction, kernel: Kernel, precision: Precision,
               fields: dict[int, list[str]]) -> str:
    if step.op == ca.OP_INPUT and step.port in fields:
        return f"w{step.target} = {fields[step.port][step.element]};"
    if step.op == ca.OP_INPUT:
        return f"w{step.target} = {kernel.inputs[step.port].name}[{step.element}];"
    if step.op == ca.OP_OUTPUT:
        return f"{kernel.outputs[step.port].name}[{step.element}] = w{step.args[0]};"
    if step.op == ca.OP_CONST:
        return f"w{step.target} = {literal(step.constant, precision)};"
    if step.op not in OPERATIONS:
        raise KernelError(f"kernel {kernel.name!r}: CasADi operation {step.op_name} "
                          "has no C translation")
    arity, pattern = OPERATIONS[step.op]
    if len(step.args) != arity:
        raise KernelError(f"kernel {kernel.name!r}: {step.op_name} with {len(step.args)} "
                          f"operands, expected {arity}")
    expression = pattern.format(*(f"w{r}" for r in step.args), fs=precision.math_suffix,
                                one=literal(1.0, precision), zero=literal(0.0, precision))
    return f"w{step.target} = {expression};"


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
        text = next(t for t in (f"{value:.{digits}g}" for digits in range(1, 10))
                    if float(np.float32(float(t))) == value)
        text += "" if any(c in text for c in ".e") else ".0"
    else:
        text = repr(value)
    return text + precision.literal_suffix
