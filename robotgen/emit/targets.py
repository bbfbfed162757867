"""Embedded targets: the emitted C compiled for a microcontroller, each function's size.

``robotgen build --target cortex-m7`` compiles ``<name>.c`` with the Arm GNU toolchain
(``arm-none-eabi-gcc``) as a Cortex-M7 with its double-precision FPU would, warning-free
under -Wall -Wextra -Werror -Wdouble-promotion, and records in manifest.json each function's
code bytes (``arm-none-eabi-nm -S``) and stack bytes (``-fstack-usage``: its own frame, and
with the frames of what it calls in the same object), the object's text,
data and bss, and the compiler's version: what a firmware engineer needs to know before
linking. The numbers depend on that compiler's version, which is why only a build that asks
for a target has them (the manifest of a plain build is the same on every machine).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

TARGETS = {
    "cortex-m7": (
        "arm-none-eabi-gcc",
        [
            "-mcpu=cortex-m7",
            "-mfpu=fpv5-d16",
            "-mfloat-abi=hard",
            "-mthumb",
            "-O2",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-Wdouble-promotion",
        ],
    ),
}
INSTALL_HINT = "Debian and Ubuntu: apt-get install gcc-arm-none-eabi"


class TargetUnavailable(Exception):
    """The target's compiler is not installed: the user's to fix (exit 1)."""


def check_available(target: str) -> None:
    """Raise TargetUnavailable unless the target's compiler, nm, size and objdump are on PATH."""
    compiler, _ = TARGETS[target]
    for tool in (compiler, *(_sibling(compiler, t) for t in ("nm", "size", "objdump"))):
        if shutil.which(tool) is None:
            raise TargetUnavailable(f"--target {target} needs {tool} on PATH ({INSTALL_HINT})")


def measure(target: str, source_dir: Path, name: str) -> dict:
    """Compiles ``source_dir/<name>.c`` for ``target``; the manifest's report of it."""
    check_available(target)
    compiler, flags = TARGETS[target]
    source_dir = Path(source_dir).resolve()  # the compiler runs in a directory of its own
    with tempfile.TemporaryDirectory(prefix="robotgen-target-") as work:
        obj = Path(work) / f"{name}.o"
        result = subprocess.run(
            [
                compiler,
                *flags,
                "-fstack-usage",
                "-I",
                str(source_dir),
                "-c",
                str(source_dir / f"{name}.c"),
                "-o",
                str(obj),
            ],
            capture_output=True,
            text=True,
            cwd=work,
        )
        if result.returncode != 0:
            raise RuntimeError(f"{compiler} failed on the emitted {name}.c:\n{result.stderr}")
        code = _function_sizes(_tool(compiler, "nm", "-S", str(obj)))
        stack = _stack_usage((Path(work) / f"{name}.su").read_text())
        calls = _calls(_tool(compiler, "objdump", "-dr", str(obj)))
        text, data, bss = (int(v) for v in _tool(compiler, "size", str(obj)).splitlines()[1].split()[:3])
        version = _tool(compiler, "", "--version").splitlines()[0]
    return {
        "compiler": version,
        "flags": flags,
        "text_bytes": text,
        "data_bytes": data,
        "bss_bytes": bss,
        "functions": {
            f: {"code_bytes": code[f], "stack_bytes": stack[f], "stack_bytes_with_calls": _deepest(f, stack, calls)}
            for f in sorted(code)
        },
    }


def _sibling(compiler: str, tool: str) -> str:
    """arm-none-eabi-gcc -> arm-none-eabi-nm."""
    return compiler[: compiler.rindex("-") + 1] + tool


def _tool(compiler: str, tool: str, *args: str) -> str:
    program = _sibling(compiler, tool) if tool else compiler
    return subprocess.run([program, *args], capture_output=True, text=True, check=True).stdout


def _function_sizes(nm: str) -> dict[str, int]:
    """Code bytes of each function (text symbols, local ones included) from ``nm -S``."""
    sizes = {}
    for line in nm.splitlines():
        fields = line.split()
        if len(fields) == 4 and fields[2] in "Tt":
            sizes[fields[3]] = int(fields[1], 16)
    return sizes


def _calls(objdump: str) -> dict[str, tuple[set[str], set[str]]]:
    """The functions each function calls (bl) and those it ends in (a tail call: b to another
    function, its own frame already popped), from ``objdump -dr``."""
    calls: dict[str, tuple[set[str], set[str]]] = {}
    current = None
    for line in objdump.splitlines():
        header = re.match(r"[0-9a-f]+ <([\w.]+)>:$", line)
        if header:
            current = header.group(1)
            calls[current] = (set(), set())
            continue
        branch = re.search(r"\s(bl|b[a-z]{0,2}(?:\.[nw])?)\s+[0-9a-f]+ <([\w.]+?)(?:\+0x[0-9a-f]+)?>", line)
        if branch and current is not None and branch.group(2) != current:
            calls[current][0 if branch.group(1) == "bl" else 1].add(branch.group(2))
    return calls


def _deepest(function: str, stack: dict[str, int], calls: dict[str, tuple[set[str], set[str]]]) -> int:
    """Stack bytes of ``function`` and its deepest chain of calls into this object (the
    emitted code does not recurse); <math.h> functions, defined elsewhere, count nothing."""
    called, tail = calls.get(function, (set(), set()))
    inner = [_deepest(f, stack, calls) for f in called if f in stack]
    after = [_deepest(f, stack, calls) for f in tail if f in stack]
    return max([stack[function] + max(inner, default=0), *after])


def _stack_usage(su: str) -> dict[str, int]:
    """Stack bytes of each function from gcc's .su file; every frame must be static. Names
    may carry gcc's suffixes for the parts it splits off (``f.part.0``, ``f.isra.0``)."""
    stack = {}
    for line in su.splitlines():
        match = re.match(r".*:([\w.]+)\t(\d+)\t([\w,]+)$", line)
        if not match or match.group(3) != "static":
            raise RuntimeError(f"a stack frame that is not of fixed size: {line!r}")
        stack[match.group(1)] = int(match.group(2))
    return stack
