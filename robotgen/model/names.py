"""What a module name may be: it becomes a Python module, the prefix of every C function, and
the names of the emitted files (<name>.c, <name>.h, <name>_module.c, lib<name>.a), so it must be
an identifier in both languages and must not stand where a standard name is expected."""

from __future__ import annotations

import keyword
import re
import sys

SPELLING = "[a-z_][a-z0-9_]*"  # also the schema's pattern
PATTERN = re.compile(SPELLING + r"\Z")
MAX_LENGTH = 64  # the longest emitted file name, <name>.cpython-3xx-<platform>.so, stays far below 255

C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int "
    "long register restrict return short signed sizeof static struct switch typedef union unsigned void "
    "volatile while".split()
)
# <name>.h beside the code would be found by #include <math.h> in place of the standard header
C_HEADERS = frozenset(
    "assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdalign stdarg "
    "stdatomic stdbool stddef stdint stdio stdlib stdnoreturn string tgmath threads time uchar wchar "
    "wctype".split()
)
# modules a user of the generated module imports beside it
PYTHON_PACKAGES = frozenset({"numpy", "casadi", "robotgen", "scipy", "matplotlib", "yaml", "pinocchio"})
OTHER = frozenset({"main"})  # the C entry point


def name_problem(name: str) -> str | None:
    """Why ``name`` cannot name a module, or None."""
    if not PATTERN.match(name):
        return "is not a module name: lower-case letters, digits and _, not starting with a digit"
    if len(name) > MAX_LENGTH:
        return f"is {len(name)} characters long; a module name has at most {MAX_LENGTH}"
    if name in C_KEYWORDS or keyword.iskeyword(name):
        return f"is a {'C' if name in C_KEYWORDS else 'Python'} keyword"
    if name.startswith("__"):
        return "starts with __, which Python reserves"
    if name in C_HEADERS:
        return f"would emit {name}.h, which hides the standard header <{name}.h>"
    if name in sys.stdlib_module_names or name in PYTHON_PACKAGES:
        return f"would hide the Python module {name!r}"
    if name in OTHER:
        return "is the name of C's entry point"
    return None
