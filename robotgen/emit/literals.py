"""Text as C and Python string literals, for the emitted docstrings and comments."""

from __future__ import annotations


def c_string(text: str) -> str:
    """``text`` as adjacent C string literals, one per line of text; ASCII only."""
    pieces = []
    for line in text.splitlines(keepends=True) or [""]:
        escaped = "".join(_c_char(c) for c in line.encode("utf-8"))
        pieces.append(f'"{escaped}"')
    return "\n    ".join(pieces)


def py_string(text: str) -> str:
    """``text`` as a triple-quoted Python string literal (a docstring); ASCII only."""
    return '"""' + "".join(_py_char(c) for c in text) + '"""'


def _py_char(char: str) -> str:
    if char == "\n":
        return char
    if char in '"\\':
        return "\\" + char
    if 32 <= ord(char) < 127:
        return char
    return f"\\x{ord(char):02x}" if ord(char) < 256 else char.encode("unicode_escape").decode()


def _c_char(byte: int) -> str:
    char = chr(byte)
    if char == "\n":
        return "\\n"
    if char in '"\\?':  # '?' escaped so no trigraph forms under -std=c99
        return "\\" + char
    if 32 <= byte < 127:
        return char
    return f"\\{byte:03o}"
