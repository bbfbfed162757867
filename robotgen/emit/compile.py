"""Compiles the Python extension with the C compiler Python was built with."""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import sysconfig
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

WARNING_FLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror")
# No a * b + c fused into one multiply-add, whatever $CFLAGS asks for the instruction set: gcc
# does not fuse under -std=c99, clang does within an expression (its sin/cos polynomials) unless told
SAME_BITS_FLAGS = ("-ffp-contract=off",)


class CompileError(RuntimeError):
    """The compiler rejected generated code: a robotgen bug (message holds its output)."""


class CompilerSetupError(OSError):
    """The machine's compiler setup, not a robotgen bug: the user's to mend."""


class NoCompiler(CompilerSetupError):
    """The C compiler named by $CC (or Python's build configuration) is not there."""


class FlagsRejected(CompilerSetupError):
    """The compiler failed with the user's $CFLAGS (their flags, not the generated code, are
    the first suspect)."""


def extension_suffix() -> str:
    """The file suffix of a Python extension module on this interpreter (e.g. .cpython-311-x86_64-linux-gnu.so)."""
    return sysconfig.get_config_var("EXT_SUFFIX") or ".so"


def compiler() -> list[str]:
    """$CC if set, else the compiler from Python's build configuration, else ``cc``."""
    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")


def user_flags() -> list[str]:
    """$CFLAGS, placed after robotgen's -O2 (so -O3 or -march=native take effect) and before
    -std=c99 and SAME_BITS_FLAGS, so that a build for a wider instruction set computes the
    portable build's bits."""
    return shlex.split(os.environ.get("CFLAGS", ""))


def compile_extension(build_dir: Path, name: str, sources: list[str], parts: int = 1) -> Path:
    """Builds ``<name><EXT_SUFFIX>`` in ``build_dir`` from the named sources there. With
    ``parts`` > 1, ``<name>.c`` is compiled as that many parts (-DRG_PART=k), every source to an
    object, as many compilers at once as the machine has cores, then linked."""
    paths = sysconfig.get_paths()
    includes = dict.fromkeys([paths["include"], paths["platinclude"], np.get_include()])
    target = name + extension_suffix()
    flags = ["-O2", "-fPIC", *user_flags(), *WARNING_FLAGS, *SAME_BITS_FLAGS, *(f"-I{d}" for d in includes)]
    link = ["-shared", *(["-undefined", "dynamic_lookup"] if sys.platform == "darwin" else [])]
    if parts <= 1:
        _run([*compiler(), *flags, *link, *sources, "-o", target, "-lm"], build_dir, name)
        return build_dir / target
    jobs = []
    for source in sources:
        stem = source[:-2]
        if source == f"{name}.c":
            jobs += [
                [*compiler(), *flags, f"-DRG_PART={k}", "-c", source, "-o", f"{stem}.part{k}.o"] for k in range(parts)
            ]
        else:
            jobs.append([*compiler(), *flags, "-c", source, "-o", f"{stem}.o"])
    objects = [job[-1] for job in jobs]
    try:
        with ThreadPoolExecutor(max_workers=max(1, min(len(jobs), os.cpu_count() or 1))) as pool:
            for future in [pool.submit(_run, job, build_dir, name) for job in jobs]:
                future.result()
        _run([*compiler(), *link, *objects, "-o", target, "-lm"], build_dir, name)
    finally:
        for obj in objects:
            (build_dir / obj).unlink(missing_ok=True)
    return build_dir / target


def _run(command: list[str], build_dir: Path, name: str) -> None:
    try:
        result = subprocess.run(command, cwd=build_dir, capture_output=True, text=True)
    except FileNotFoundError as error:
        raise NoCompiler(
            f"no C compiler: cannot run {command[0]!r} ({error.strerror}); install one (gcc or clang) "
            "or set CC to it, or build with --no-compile"
        ) from None
    if result.returncode != 0:
        if user_flags():
            raise FlagsRejected(
                f"compiling the generated extension {name!r} failed with CFLAGS={shlex.join(user_flags())!r} "
                f"from the environment; unset CFLAGS to build with robotgen's own flags:\n"
                f"$ {shlex.join(command)}\n{result.stdout}{result.stderr}"
            )
        raise CompileError(
            f"compiling the generated extension {name!r} failed (a robotgen bug):\n"
            f"$ {shlex.join(command)}\n{result.stdout}{result.stderr}"
        )
