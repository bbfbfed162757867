"""Read a spec file, keep where every key and value stands, and check it against the schema.

ruamel.yaml's round-trip loader records the line and column of every mapping key, mapping
value and sequence item; ``SourceMap`` turns a path into the document (("nodes", "arm",
"define", "chain", "joints", 2)) into a ``Location``. Schema errors are reported at the
offending value, at the unknown key, or at the key holding a mapping that lacks a key.
"""

from __future__ import annotations

import functools
import hashlib
import re
import sys
from dataclasses import dataclass, replace
from typing import Any

from jsonschema import Draft202012Validator, ValidationError
from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedSeq
from ruamel.yaml.constructor import ConstructorError, RoundTripConstructor
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from robotgen.errors import Location, UserError, UserErrors
from robotgen.frontend.input_file import read_input
from robotgen.frontend.schema import spec_schema
from robotgen.model.laws.registry import LAWS

Path = tuple[str | int, ...]


@functools.cache
def _validator(laws: tuple) -> Draft202012Validator:
    """The schema's validator, made once for the laws of the registry (``laws``, its entries)."""
    return Draft202012Validator(spec_schema())


_TYPE_NAMES = {
    "object": "a mapping",
    "array": "a list",
    "string": "a string",
    "number": "a number",
    "integer": "an integer",
    "boolean": "true or false",
    "null": "nothing",
}


def format_path(data: object, path: Path) -> str:
    """``nodes.arm.define.chain.joints[2].link.mass``: sequence indices in brackets."""
    text = ""
    node: Any = data  # walks arbitrary YAML data
    for part in path:
        if isinstance(node, list):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            node = None
    return text


def describe(value: object) -> str:
    """A value as a message shows it."""
    if value is None:
        return "nothing"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        return f"the string {_quoted(value)}"
    return repr(value)


def _quoted(text: str, limit: int = 60) -> str:
    """At most one line of ``text``, cut to ``limit`` characters: a message never echoes a
    whole file back (`robotgen check /etc/passwd`)."""
    lines = text.splitlines() or [""]
    first = lines[0]
    cut = len(first) > limit or len(lines) > 1
    return repr(first[:limit]) + (" ..." if cut else "")


class SourceMap:
    """Locations of the keys and values of a round-trip-loaded YAML document."""

    def __init__(self, file: str, root: object, lines: list[str]):
        self.file = file
        self.root = root
        self.lines = lines

    def _walk(self, path: Path) -> tuple[Location, Location]:
        """(key, value) locations of the node at ``path``; for a sequence item both are the
        item. Falls back to the closest located ancestor (e.g. keys from YAML merges)."""
        key = value = self._location(
            getattr(getattr(self.root, "lc", None), "line", 0), getattr(getattr(self.root, "lc", None), "col", 0)
        )
        node: Any = self.root  # ruamel's CommentedMap and CommentedSeq, with their .lc positions
        for part in path:
            try:
                if isinstance(node, CommentedSeq):
                    key = value = self._location(*node.lc.item(part))
                else:
                    key = self._location(*node.lc.key(part))
                    value = self._location(*node.lc.value(part))
                node = node[part]
            except (KeyError, IndexError, TypeError, AttributeError):
                break
        return key, value

    def _location(self, line: int, col: int) -> Location:
        return Location(self.file, line + 1, col + 1)

    def key(self, path: Path) -> Location:
        """The key (or sequence item) that holds ``path``: where a field is named."""
        return self._walk(path)[0]

    def value(self, path: Path) -> Location:
        """The first character of the value at ``path`` (a quote for quoted scalars)."""
        return self._walk(path)[1]

    def text_start(self, path: Path, text: str) -> tuple[Location, bool]:
        """Where the string ``text`` at ``path`` starts in the file, and whether it stands
        there verbatim on one line (so columns inside it are columns in the file)."""
        at = self.value(path)
        line = self.lines[at.line - 1] if at.line <= len(self.lines) else ""
        col = at.col - 1
        if line[col : col + len(text)] == text:
            return at, True
        if line[col : col + 1] in ("'", '"') and line[col + 1 : col + 1 + len(text)] == text:
            return replace(at, col=at.col + 1), True
        return at, False


@dataclass(frozen=True, eq=False)
class Document:
    """A spec file read and schema-checked: plain data (dicts, lists, str, int, float, bool,
    None) plus where each part of it stands."""

    path: str
    data: dict
    source: SourceMap
    sha256: str


def _read(path: str) -> tuple[bytes, str]:
    try:
        raw = read_input(path, MAX_BYTES, "spec", " (robot models that large belong in a URDF leaf)")
    except UserError as error:
        raise UserErrors([error]) from None
    try:
        return raw, raw.decode("utf-8")
    except UnicodeDecodeError as error:
        line = raw[: error.start].count(b"\n") + 1
        raise UserErrors([UserError(Location(path, line), "spec is not UTF-8 text")]) from None


# Bounds on what a spec may be, checked before anything is built: a real spec nests a dozen
# levels and holds a few thousand values. Deeper nesting would exhaust the parser's recursion;
# YAML aliases can make a small file stand for exponentially many values ("billion laughs").
MAX_DEPTH = 64
MAX_VALUES = 100_000
MAX_BYTES = 1_000_000


# A block scalar's indicator (| or >, with its chomping and indentation indicators) at the end
# of a line: the lines indented deeper than that line are its text.
_BLOCK_SCALAR = re.compile(r"(?:^|[\s:-])[|>][+-]?[1-9]?[+-]?\s*$")


def _check_bounds(path: str, text: str) -> int:
    """Bounds checked on the text before the YAML parser reads it: flow collections ([ {)
    nested deeper than MAX_DEPTH, block nesting that deep (indentation of more than
    4 * MAX_DEPTH columns), and more than MAX_VALUES entries, each a located error. ruamel's
    parser takes 25-40 us and about 1.5 kB per value, so a 1 MB flow list of 480,000 numbers
    took minutes and 0.7 GB before the count of values was seen; here it is refused after
    reading the text once. Counted are the entries that are each at least one value: a comma
    inside a flow collection, a block sequence's "- " and a block mapping's "key:" (text in
    quotes, comments and block scalars is skipped), so the count never exceeds the values the
    parser would make; _plain counts them exactly afterwards (aliases as often as used).
    Returns that count."""
    depth, quote, entries = 0, "", 0
    block_scalar = None  # indentation of the line that opened a block scalar
    for number, line in enumerate(text.splitlines(), 1):
        indent = len(line) - len(line.lstrip(" "))
        body = line.strip()
        if block_scalar is not None:
            if not body or indent > block_scalar:
                continue
            block_scalar = None
        if indent > 4 * MAX_DEPTH:
            raise UserErrors(
                [
                    UserError(
                        Location(path, number, 1),
                        f"YAML: indented {indent} columns: nested deeper than the {MAX_DEPTH} levels a spec may have",
                    )
                ]
            )
        start, code_end, keyed = indent + 1, len(line), False
        if depth == 0:  # block sequence items: "- - a: 1" holds two, and a mapping entry
            rest = body
            while rest == "-" or rest[:2] in ("- ", "-\t"):
                entries += 1
                rest = rest[1:].lstrip()
            start = len(line) - len(rest) + 1
        column = start
        for column, char in enumerate(line[start - 1 :], start):
            if quote:
                quote = "" if char == quote else quote
            elif char in "'\"":
                quote = char
            elif char == "#" and (column == 1 or line[column - 2] in " \t"):
                code_end = column - 1
                break
            elif char in "[{":
                depth += 1
                if depth > MAX_DEPTH:
                    raise UserErrors(
                        [
                            UserError(
                                Location(path, number, column),
                                f"YAML: collections nested deeper than the {MAX_DEPTH} levels a spec may have",
                            )
                        ]
                    )
            elif char in "]}":
                depth = max(depth - 1, 0)
            elif char == "," and depth:
                entries += 1
            elif char == ":" and not depth and not keyed and line[column : column + 1] in ("", " ", "\t"):
                entries, keyed = entries + 1, True
            if entries > MAX_VALUES:
                break
        if entries > MAX_VALUES:
            raise UserErrors(
                [
                    UserError(
                        Location(path, number, column),
                        f"YAML: more than {MAX_VALUES} values (list and mapping entries); a spec holds a few thousand",
                    )
                ]
            )
        if not depth and not quote and _BLOCK_SCALAR.search(line[:code_end]):
            block_scalar = indent
        quote = ""  # robotgen's values are one-line scalars; a quote never spans lines here
    return entries


class _Constructor(RoundTripConstructor):
    """ruamel's round-trip constructor, with a scalar it cannot convert made a located YAML
    error: an integer of more digits than Python converts from text (4300: a ValueError), a
    date such as 2001-13-45."""

    def construct_non_recursive_object(self, node, tag=None):
        try:
            return super().construct_non_recursive_object(node, tag)
        except (ValueError, OverflowError) as error:
            text = node.value if isinstance(node.value, str) else ""
            digits = sum(c.isdigit() for c in text)
            if (tag or node.tag).endswith(":int") and digits > sys.get_int_max_str_digits() > 0:
                reason = (
                    f"an integer of {digits} digits; robotgen reads integers of at most "
                    f"{sys.get_int_max_str_digits()} digits"
                )
            else:
                reason = f"{_quoted(text)} cannot be read: {error}"
            raise ConstructorError(None, None, reason, node.start_mark) from None


def _parse_yaml(path: str, text: str) -> object:
    _check_bounds(path, text)
    yaml = YAML(typ="rt")
    yaml.Constructor = _Constructor
    try:
        return yaml.load(text)
    except RecursionError:
        raise UserErrors(
            [UserError(Location(path), f"YAML: nested deeper than the {MAX_DEPTH} levels a spec may have")]
        ) from None
    except MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        message = error.problem or error.context or "invalid YAML"
        if error.context and error.problem and error.context_mark:
            message += f" ({error.context} at line {error.context_mark.line + 1})"
        location = Location(path, mark.line + 1, mark.column + 1) if mark else Location(path)
        raise UserErrors([UserError(location, f"YAML: {message}")]) from None
    except YAMLError as error:
        position = getattr(error, "position", None)
        location = Location(path)
        if isinstance(position, int):
            before = text[:position]
            location = Location(path, before.count("\n") + 1, position - (before.rfind("\n") + 1) + 1)
        reason = getattr(error, "reason", None) or str(error).splitlines()[0]
        raise UserErrors([UserError(location, f"YAML: {reason}")]) from None


def _plain(
    node: object, path: Path, source: SourceMap, errors: list[UserError], count: list[int] | None = None
) -> object:
    """ruamel's node types as plain Python; non-string mapping keys are errors. Stops with an
    error past MAX_DEPTH levels or MAX_VALUES values (aliases count as often as they are used)."""
    count = [0] if count is None else count
    count[0] += 1
    if count[0] > MAX_VALUES or len(path) > MAX_DEPTH:
        where = format_path(source.root, path[:MAX_DEPTH])
        what = (
            f"more than {MAX_VALUES} values (each use of a YAML alias counts)"
            if count[0] > MAX_VALUES
            else f"nesting deeper than {MAX_DEPTH} levels"
        )
        raise UserErrors([UserError(source.value(path[:MAX_DEPTH]), f"{where}: the spec holds {what}")])
    if isinstance(node, dict):
        plain = {}
        for key, value in node.items():
            if not isinstance(key, str):
                where = format_path(source.root, path)
                errors.append(
                    UserError(source.key(path + (key,)), f"{where + ': ' if where else ''}key {key!r} must be a string")
                )
                continue
            plain[str(key)] = _plain(value, path + (key,), source, errors, count)
        return plain
    if isinstance(node, list):
        return [_plain(item, path + (i,), source, errors, count) for i, item in enumerate(node)]
    if isinstance(node, bool) or node is None:
        return node
    for kind in (str, int, float):
        if isinstance(node, kind):
            return kind(node)
    return node


def _schema_errors(error: ValidationError, data: object, source: SourceMap) -> list[UserError]:
    """One schema violation as located, human messages."""
    path: Path = tuple(error.absolute_path)
    # jsonschema's stubs type these with an Unset sentinel for errors not yet reported; a
    # reported error has them all, as the JSON values they are
    instance: Any = error.instance
    schema: Any = error.schema
    kind = error.validator
    validator_value: Any = error.validator_value

    def at(location: Location, where: Path, message: str) -> UserError:
        field = format_path(data, where)
        return UserError(location, f"{field}: {message}" if field else message)

    if kind == "additionalProperties" and schema.get("additionalProperties") is False:
        allowed = ", ".join(schema.get("properties", {}))
        return [
            at(source.key(path + (k,)), path + (k,), f"unknown key (allowed: {allowed})")
            for k in instance
            if k not in schema.get("properties", {})
        ]
    if kind == "required":
        missing = [k for k in validator_value if k not in instance]
        return [at(source.key(path), path, f"missing required key '{k}'") for k in missing]
    if kind == "oneOf" and all(set(branch) == {"required"} for branch in validator_value):
        if not isinstance(instance, dict):
            return []  # not a mapping at all: its type error says so
        keys = [branch["required"][0] for branch in validator_value]
        present = [k for k in keys if k in instance]
        if not present:
            return [at(source.key(path), path, f"needs one of: {', '.join(keys)}")]
        return [
            at(source.key(path + (present[1],)), path, f"{' and '.join(present)} exclude each other; give exactly one")
        ]
    if "propertyNames" in error.schema_path:
        return [
            at(source.key(path + (instance,)), path, f"name {instance!r} is not an identifier ([A-Za-z_][A-Za-z0-9_]*)")
        ]
    if kind == "type":
        expected = validator_value if isinstance(validator_value, list) else [validator_value]
        message = f"expected {' or '.join(_TYPE_NAMES[t] for t in expected)}, got {describe(instance)}"
    elif kind == "enum":
        message = f"{instance!r} is not one of: {', '.join(map(str, validator_value))}"
    elif kind == "const":
        message = f"must be {validator_value!r}, got {describe(instance)}"
    elif kind in ("minItems", "maxItems"):
        low, high = schema.get("minItems"), schema.get("maxItems")
        bound = "exactly" if low == high else ("at least" if kind == "minItems" else "at most")
        n = low if kind == "minItems" else high
        message = f"expected {bound} {n} item{'' if n == 1 else 's'}, got {len(instance)}"
    elif kind == "minProperties":
        message = "must not be empty"
    elif kind == "pattern":
        message = f"{instance!r} must match {validator_value}"
    else:
        message = error.message
    return [at(source.value(path), path, message)]


def sort_errors(errors: list[UserError]) -> list[UserError]:
    """By position in the file, each distinct error once."""
    unique = {str(e): e for e in errors}
    return sorted(unique.values(), key=lambda e: (e.location.line, e.location.col))


def load_document(path: str) -> Document:
    """Read ``path`` and check it against the schema; raises UserErrors with every problem."""
    raw, text = _read(path)
    root = _parse_yaml(path, text)
    if not isinstance(root, dict):
        raise UserErrors([UserError(Location(path), f"a spec must be a YAML mapping, got {describe(root)}")])
    source = SourceMap(path, root, text.splitlines())
    errors: list[UserError] = []
    data = _plain(root, (), source, errors)
    assert isinstance(data, dict)  # _plain keeps a mapping a dict
    for error in _validator(tuple(LAWS.values())).iter_errors(data):
        errors += _schema_errors(error, data, source)
    if errors:
        raise UserErrors(sort_errors(errors))
    return Document(path, data, source, hashlib.sha256(raw).hexdigest())
