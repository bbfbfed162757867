"""Safe arithmetic expressions for spec formulas and constant fields.

Text is parsed by Python's ``ast`` (mode "eval") and every node is checked against a
whitelist: numbers, known names, ``+ - * / **`` (``^`` also means power), unary ``+ -``
and calls of the functions in ``FUNCTIONS`` by bare name. Spec text is never executed;
``evaluate`` walks the checked tree with a caller-supplied function library, so the same
tree becomes a float (``MATH_LIB``) or a CasADi graph (the symbolic layer's library).
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from robotgen.errors import Location, UserError
from robotgen.numeric import exact

# name -> number of arguments
FUNCTIONS: dict[str, int] = {
    "sin": 1,
    "cos": 1,
    "tan": 1,
    "asin": 1,
    "acos": 1,
    "atan": 1,
    "atan2": 2,
    "exp": 1,
    "log": 1,
    "sqrt": 1,
    "abs": 1,
    "tanh": 1,
    "sinh": 1,
    "cosh": 1,
    "sign": 1,
    "min": 2,
    "max": 2,
}
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}
# The largest magnitude of a numeric field: far beyond any robot's lengths, masses, angles or
# gains in SI units, and small enough that build-time arithmetic (products of inertias) stays
# exact.
MAX_MAGNITUDE = 1e15

_BINARY = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)
_UNARY = (ast.UAdd, ast.USub)


@dataclass(frozen=True, eq=False)
class Expr:
    """A checked expression: its source text, its tree, and where the text starts."""

    text: str
    node: ast.expr
    location: Location

    @property
    def names(self) -> frozenset[str]:
        """Every variable name the expression reads (constants pi and e excluded)."""
        return frozenset(
            n.id
            for n in ast.walk(self.node)
            if isinstance(n, ast.Name) and n.id not in FUNCTIONS and n.id not in CONSTANTS
        )


def _sign(x: float) -> float:
    return float((x > 0) - (x < 0))


# Float implementations of every whitelisted function, plus "pow" for ** and ^: correctly
# rounded (robotgen.numeric.exact), so a constant such as "pi/3" or "0.1^2" is the same double
# on every machine.
MATH_LIB: dict[str, Callable[..., float]] = {
    "sin": exact.sin,
    "cos": exact.cos,
    "tan": exact.tan,
    "asin": exact.asin,
    "acos": exact.acos,
    "atan": exact.atan,
    "atan2": exact.atan2,
    "exp": exact.exp,
    "log": exact.log,
    "sqrt": exact.sqrt,
    "abs": math.fabs,
    "tanh": exact.tanh,
    "sinh": exact.sinh,
    "cosh": exact.cosh,
    "sign": _sign,
    "min": min,
    "max": max,
    "pow": exact.power,
}


def _prepare(text: str) -> tuple[str, list[int]]:
    """Python-parsable text and, for each of its characters, the index in ``text``.
    Leading blanks are dropped, line breaks become spaces, ``^`` becomes ``**`` (so it
    keeps the precedence of power instead of Python's bitwise xor)."""
    out: list[str] = []
    origin: list[int] = []
    start = len(text) - len(text.lstrip())
    for i, ch in enumerate(text[start:], start):
        if ch == "^":
            out += "**"
            origin += [i, i]
        else:
            out.append(" " if ch in "\r\n\t" else ch)
            origin.append(i)
    origin.append(len(text))  # one past the end, for errors at end of input
    return "".join(out), origin


class _Checker:
    """Walks a parsed tree and raises UserError at the first node outside the whitelist."""

    def __init__(
        self, text: str, prepared: str, origin: list[int], location: Location, names: set[str], exact_columns: bool
    ):
        self.text = text
        self.prepared = prepared
        self.origin = origin
        self.location = location
        self.allowed = set(names) | set(CONSTANTS)
        self.exact_columns = exact_columns

    def at(self, index: int) -> Location:
        """Location of character ``index`` of the prepared text."""
        if not self.exact_columns or "\n" in self.text:
            return self.location
        column = self.origin[min(max(index, 0), len(self.origin) - 1)]
        return replace(self.location, col=self.location.col + column)

    def index(self, byte_offset: int | None) -> int:
        """Character index in the prepared text of an ast byte offset."""
        return len(self.prepared.encode("utf-8")[:byte_offset].decode("utf-8", errors="ignore"))

    def token_after(self, node: ast.expr, token: str) -> int:
        """Index of the first ``token`` after ``node`` (an operator, a dot, a bracket)."""
        found = self.prepared.find(token, self.index(node.end_col_offset))
        return found if found >= 0 else self.index(node.col_offset)

    def fail(self, node: ast.expr | ast.keyword, message: str) -> UserError:
        """Error at the token that makes ``node`` illegal."""
        if isinstance(node, ast.BinOp):
            start = self.index(node.left.end_col_offset)
            rest = self.prepared[start : self.index(node.right.col_offset)]
            index = start + len(rest) - len(rest.lstrip(" ()"))
        elif isinstance(node, ast.Attribute):
            index = self.token_after(node.value, ".")
        elif isinstance(node, ast.Subscript):
            index = self.token_after(node.value, "[")
        else:
            index = self.index(node.col_offset)
        return UserError(self.at(index), message)

    def check(self, node: ast.expr) -> None:
        if isinstance(node, ast.Constant):
            self.check_number(node)
        elif isinstance(node, ast.Name):
            if node.id in FUNCTIONS:
                raise self.fail(node, f"function '{node.id}' must be called, e.g. {node.id}(x)")
            if node.id not in self.allowed:
                raise self.fail(node, f"unknown name '{node.id}' (allowed: {', '.join(sorted(self.allowed))})")
        elif isinstance(node, ast.BinOp):
            if not isinstance(node.op, _BINARY):
                raise self.fail(node, "operator not allowed (allowed: + - * / ** ^)")
            self.check(node.left)
            self.check(node.right)
        elif isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, _UNARY):
                raise self.fail(node, "only unary + and - are allowed")
            self.check(node.operand)
        elif isinstance(node, ast.Call):
            self.check_call(node)
        else:
            raise self.fail(node, f"{_describe(node)} is not allowed in an expression")

    def check_number(self, node: ast.Constant) -> None:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(node, f"{_describe(node)} is not allowed in an expression")
        try:
            finite = math.isfinite(float(value))
        except OverflowError:
            finite = False
        if not finite:
            raise self.fail(node, f"number {self.text_of(node)!r} is out of range")

    def check_call(self, node: ast.Call) -> None:
        if not isinstance(node.func, ast.Name):
            raise self.fail(node.func, f"only the functions {', '.join(FUNCTIONS)} can be called")
        name = node.func.id
        if name not in FUNCTIONS:
            raise self.fail(node.func, f"'{name}' is not a known function (known: {', '.join(FUNCTIONS)})")
        if node.keywords:
            raise self.fail(node.keywords[0], f"{name}() takes no keyword arguments")
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                raise self.fail(arg, f"{name}() takes no unpacked arguments")
        arity = FUNCTIONS[name]
        if len(node.args) != arity:
            raise self.fail(node, f"{name}() takes {arity} argument{'s' if arity > 1 else ''}, got {len(node.args)}")
        for arg in node.args:
            self.check(arg)

    def text_of(self, node: ast.AST) -> str:
        return ast.get_source_segment(self.prepared, node) or ""

    def check_constants(self, node: ast.expr) -> float | None:
        """The value of ``node`` if it reads no variable (None otherwise), so that every
        constant part of a formula, which the build folds into one number, is a finite real
        number: 1/0, 10^400, exp(1000), sqrt(-1), log(0) are located errors, not NaN or
        infinite literals in the emitted C."""
        if isinstance(node, ast.Constant):
            return _number(node)
        if isinstance(node, ast.Name):
            return CONSTANTS.get(node.id) if node.id not in self.allowed - set(CONSTANTS) else None
        if isinstance(node, ast.UnaryOp):
            parts = [node.operand]
        elif isinstance(node, ast.BinOp):
            parts = [node.left, node.right]
        elif isinstance(node, ast.Call):
            parts = list(node.args)
        else:
            raise TypeError(f"unchecked expression node {type(node).__name__}")
        values = [v for v in (self.check_constants(part) for part in parts) if v is not None]
        if len(values) < len(parts):
            return None
        value: object
        try:
            if isinstance(node, ast.UnaryOp):
                value = -values[0] if isinstance(node.op, ast.USub) else values[0]
            elif isinstance(node, ast.BinOp):
                value = _FLOAT_BINARY[type(node.op)](*values)
            else:
                value = _FLOAT_LIB[_called(node)](*values)
        except (ArithmeticError, ValueError) as error:
            reason = (
                "division by zero"
                if isinstance(error, ZeroDivisionError)
                else "too large"
                if isinstance(error, OverflowError)
                else "outside the function's domain"
            )
            raise self.fail(node, f"the constant {self.shown(node)!r} cannot be evaluated ({reason})") from None
        if not isinstance(value, float) or not math.isfinite(value):
            raise self.fail(node, f"the constant {self.shown(node)!r} is not a finite real number")
        return value

    def shown(self, node: ast.AST) -> str:
        """``node``'s text as the user wrote it (^ for a power where the text has it)."""
        text = self.text_of(node)
        return text.replace("**", "^") if "^" in self.text else text


# Plain float arithmetic for check_constants (only whether a constant part is finite and real
# is asked of it; the value the build uses comes from MATH_LIB or CasADi).
_FLOAT_BINARY: dict[type, Callable[[float, float], object]] = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
}
_FLOAT_LIB: dict[str, Callable[..., float]] = {
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "asin": math.asin,
    "acos": math.acos,
    "atan": math.atan,
    "atan2": math.atan2,
    "exp": math.exp,
    "log": math.log,
    "sqrt": math.sqrt,
    "abs": math.fabs,
    "tanh": math.tanh,
    "sinh": math.sinh,
    "cosh": math.cosh,
    "sign": _sign,
    "min": min,
    "max": max,
}


def _number(node: ast.Constant) -> float:
    """A checked number constant's value (Checker.check_number refused every other constant)."""
    if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
        raise TypeError(f"unchecked constant {node.value!r}")
    return float(node.value)


def _called(node: ast.Call) -> str:
    """The name of the function a checked call calls (Checker.check_call refused every other callee)."""
    if not isinstance(node.func, ast.Name):
        raise TypeError(f"unchecked callee {type(node.func).__name__}")
    return node.func.id


def _describe(node: ast.AST) -> str:
    kinds = {
        ast.Attribute: "attribute access",
        ast.Subscript: "indexing",
        ast.Lambda: "lambda",
        ast.Compare: "comparison",
        ast.BoolOp: "boolean operator",
        ast.IfExp: "conditional",
        ast.Tuple: "tuple",
        ast.List: "list",
        ast.Dict: "dict",
        ast.Set: "set",
        ast.ListComp: "comprehension",
        ast.SetComp: "comprehension",
        ast.DictComp: "comprehension",
        ast.GeneratorExp: "comprehension",
        ast.NamedExpr: "assignment",
        ast.Starred: "unpacking",
        ast.JoinedStr: "string",
        ast.Await: "await",
        ast.Yield: "yield",
        ast.YieldFrom: "yield",
        ast.Slice: "slice",
    }
    if isinstance(node, ast.Constant):
        if isinstance(node.value, str):
            return "a string"
        return f"constant {node.value!r}"
    return kinds.get(type(node), type(node).__name__)


def parse_expression(text: object, location: Location, names: set[str], *, exact_columns: bool = True) -> Expr:
    """Parse and check ``text``; names it may read are ``names`` plus pi and e.

    ``location`` is where the first character of ``text`` stands in the file. Errors point
    at the offending token (``location`` plus its column in ``text``); with
    ``exact_columns=False`` (the text does not stand verbatim on one line, e.g. a folded
    YAML scalar) they point at ``location`` itself."""
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise UserError(location, f"expected a number or an expression, got {text!r}")
    if not isinstance(text, str):
        try:
            finite = math.isfinite(text)
        except OverflowError:  # an integer past the largest double (YAML reads up to 4300 digits)
            raise UserError(
                location,
                f"the integer (about 10^{int(math.log10(abs(text)))}) is out of range (a double reaches 1.8e308)",
            ) from None
        if not finite:
            raise UserError(location, f"number {text!r} is not finite")
        return Expr(repr(text), ast.Constant(value=text, lineno=1, col_offset=0), location)
    prepared, origin = _prepare(text)
    checker = _Checker(text, prepared, origin, location, names, exact_columns)
    if not prepared.strip():
        raise UserError(location, "empty expression")
    if not prepared.isascii():  # Python would read look-alikes (ｍ2, sⅰn, ℯ) as other names (NFKC)
        index = next(i for i, c in enumerate(prepared) if not c.isascii())
        raise UserError(
            checker.at(index),
            f"character {prepared[index]!r} (U+{ord(prepared[index]):04X}) "
            "is not allowed in an expression: names and numbers are ASCII",
        )
    if "#" in prepared:  # Python's parser would drop the rest as a comment: "1 # + q^2" would read as 1
        raise UserError(
            checker.at(prepared.index("#")),
            "'#' is not allowed in an expression (Python would drop the text after it as a comment)",
        )
    try:
        tree = ast.parse(prepared, mode="eval")
    except SyntaxError as error:
        where = checker.at((error.offset or 1) - 1) if (error.lineno or 1) == 1 else location
        raise UserError(where, f"syntax error in expression {text!r}: {error.msg}") from None
    except (ValueError, RecursionError, MemoryError) as error:
        raise UserError(location, f"cannot parse expression: {error}") from None
    try:
        checker.check(tree.body)
        checker.check_constants(tree.body)
    except RecursionError:
        raise UserError(location, "expression is nested too deeply") from None
    return Expr(text, tree.body, location)


def _function(lib: object, name: str) -> Callable[..., object] | None:
    if isinstance(lib, Mapping):
        return lib.get(name)
    return getattr(lib, name, None)


def evaluate(expr: Expr, env: Mapping[str, object], lib: object) -> Any:
    """Value of ``expr`` with names bound by ``env`` (pi and e default to math's).

    ``lib`` maps each name of ``FUNCTIONS`` to a callable, as a mapping or as attributes;
    an optional ``pow`` entry implements ``**`` and ``^`` (default: Python's ``**``).
    Numbers enter as floats, so integer powers never grow into huge Python ints. The value is
    whatever ``lib``'s functions and the operators make of floats and ``env``'s values (a float,
    a CasADi SX, ...), hence Any."""
    power = _function(lib, "pow") or (lambda a, b: a**b)

    def visit(node: ast.expr) -> Any:
        if isinstance(node, ast.Constant):
            return _number(node)
        if isinstance(node, ast.Name):
            return env[node.id] if node.id in env else CONSTANTS[node.id]
        if isinstance(node, ast.UnaryOp):
            value = visit(node.operand)
            return -value if isinstance(node.op, ast.USub) else +value
        if isinstance(node, ast.BinOp):
            left, right = visit(node.left), visit(node.right)
            op = type(node.op)
            if op is ast.Add:
                return left + right
            if op is ast.Sub:
                return left - right
            if op is ast.Mult:
                return left * right
            if op is ast.Div:
                return left / right
            return power(left, right)
        if isinstance(node, ast.Call):
            function = _function(lib, _called(node))
            if function is None:
                raise KeyError(f"function library has no '{_called(node)}'")
            return function(*(visit(arg) for arg in node.args))
        raise TypeError(f"unchecked expression node {type(node).__name__}")

    return visit(expr.node)


def parse_constant(value: object, location: Location, *, exact_columns: bool = True) -> float:
    """A numeric field: a YAML number, or a string holding a constant expression such as
    "pi/2" (no names but pi and e)."""
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise UserError(location, f"expected a number, got {value!r}")
    expr = parse_expression(value, location, set(), exact_columns=exact_columns)
    try:
        result = float(evaluate(expr, {}, MATH_LIB))
    except (ArithmeticError, ValueError) as error:
        raise UserError(location, f"cannot evaluate {expr.text!r}: {error}") from None
    if not math.isfinite(result):
        raise UserError(location, f"{expr.text!r} is not a finite number")
    if abs(result) > MAX_MAGNITUDE:
        raise UserError(
            location,
            f"{expr.text!r} is too large: a spec's numbers (SI units) are at most {MAX_MAGNITUDE:g} in magnitude",
        )
    return result
