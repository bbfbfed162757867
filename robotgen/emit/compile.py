"""Compiles the Python extension with the C compiler Python was built with."""
from __future__ import annotations

import os
import shlex
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np

WARNING_FLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror")


class CompileError(RuntimeError):
    """The compiler rejected generated code: a robotgen bug (message holds its output)."""


class NoCompiler(OSError):
    """The C compiler named by $CC (or Python's build configuration) is not there: the
    machine's setup, not a robotgen bug."""


def extension_suffix() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


def compiler() -> list[str]:
    """$CC if set, else the compiler from Python's build configuration, else ``cc``."""
    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")


def compile_extension(build_dir: Path, name: str, sources: list[str]) -> Path:
    """Builds ``<name><EXT_SUFFIX>`` in ``build_dir`` from the named sources there."""
    paths = sysconfig.get_paths()
    includes = dict.fromkeys([paths["include"], paths["platinclude"], np.get_include()])
    target = name + extension_suffix()
    command = [*compiler(), "-O2", "-shared", "-fPIC", *WARNING_FLAGS,
               *(f"-I{d}" for d in includes), *sources, "-o", target, "-lm"]
    if sys.platform == "darwin":
        command[1:1] = ["-undefined", "dynamic_lookup"]
    try:
        result = subprocess.run(command, cwd=build_dir, capture_output=True, text=True)
    except FileNotFoundError as error:
        raise NoCompiler(f"no C compiler: cannot run {command[0]!r} ({error.strerror}); install one (gcc or clang) "
                         "or set CC to it, or build with --no-compile") from None
    if result.returncode != 0:
        raise CompileError(
            f"compiling the generated extension {name!r} failed (a robotgen bug):\n"
            f"$ {shlex.join(command)}\n{result.stdout}{result.stderr}")
    return build_dir / target
