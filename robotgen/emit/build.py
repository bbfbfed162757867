"""Writes a generated module's directory atomically: all or nothing, and replacing only what
robotgen can prove it wrote (robotgen.emit.output_directory)."""

from __future__ import annotations

import importlib
import os
import shutil
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from pathlib import Path
from types import ModuleType

from robotgen import interrupts
from robotgen.emit import cache
from robotgen.emit import compile as compiler
from robotgen.emit.context import module_view
from robotgen.emit.manifest import manifest_json
from robotgen.emit.output_directory import MANIFEST, remove_written, replace_problem
from robotgen.emit.render import render_all
from robotgen.emit.targets import measure as measure_target
from robotgen.errors import OutputError
from robotgen.output_files import output_errors, sibling
from robotgen.progress import QUIET, Progress
from robotgen.symbolic.kernel import Kernel
from robotgen.symbolic.rate_steps import MultiRate
from robotgen.symbolic.root_laws.law import Controller


def _posix_locks() -> ModuleType | None:
    """The fcntl module where the platform has it (POSIX), else None."""
    try:
        return importlib.import_module("fcntl")
    except ImportError:
        return None


fcntl = _posix_locks()

__all__ = ["MANIFEST", "emit", "parent_locked", "replace_problem"]


def emit(
    out_dir: Path,
    name: str,
    kernels: list[Kernel],
    *,
    nq: int,
    precision: str = "double",
    compile: bool = True,
    extra_info: dict | None = None,
    spec_sha256: str = "",
    attributes: dict | None = None,
    progress: Progress = QUIET,
    controllers: Sequence[Controller | MultiRate] | None = None,
    targets: tuple[str, ...] = (),
    inputs: tuple[Path, ...] = (),
    build_key: str | None = None,
) -> Path:
    """Writes ``<name>.h``, ``<name>.c``, ``<name>_module.c``, the stub ``<name>.pyi``,
    ``Makefile`` (with ``<name>.pc.in`` and ``<name>Config.cmake.in``, which its ``install``
    target fills in), ``manifest.json`` and (if ``compile``) the extension
    ``<name><EXT_SUFFIX>`` to ``out_dir``, replacing a
    previous build there. ``extra_info`` adds keys to info() and the manifest (e.g.
    ``nodes``); ``attributes`` adds json-valued module attributes; ``controllers`` (each
    around kernels of ``kernels``) adds a state struct with reset and step functions to the C
    and a class to the extension (robotgen.emit.controllers). Everything is made in a
    temporary sibling directory first, so a failure leaves ``out_dir`` as it was. ``targets``
    (robotgen.emit.targets) compiles the C for those microcontrollers as well and puts each
    function's code and stack bytes in the manifest. ``inputs`` (the spec, the files it
    reads) are never replaced: an output directory holding one is refused. A directory robotgen
    may not replace, or cannot write, raises OutputError. ``build_key`` (robotgen.emit.cache)
    is stamped into the output with the rest, so that it is swapped in with it."""
    out_dir = Path(out_dir)
    view = module_view(
        name,
        kernels,
        nq=nq,
        precision=precision,
        spec_sha256=spec_sha256,
        extra_info=extra_info,
        attributes=attributes,
        progress=progress,
        controllers=tuple(controllers or ()),
    )
    sources = render_all(view)
    files = dict(sources)
    with output_errors(out_dir):
        _check_replaceable(out_dir, inputs)
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        staging = sibling(out_dir, "tmp")  # a name of its own: nothing there is deleted to make room
        staging.mkdir()  # with the umask's permissions, as the output directory will have them
    try:
        with output_errors(out_dir):
            for file_name, text in files.items():
                (staging / file_name).write_bytes(text.encode("utf-8"))
        reports = {}
        for target in targets:
            progress.stage(f"compiling for {target}")
            reports[target] = measure_target(target, staging, name)
        with output_errors(out_dir):
            (staging / MANIFEST).write_bytes(manifest_json(view, sources, reports).encode("utf-8"))
        if compile:
            progress.stage(f"compiling the extension ({' '.join(compiler.compiler())})")
            compiler.compile_extension(staging, name, [f"{name}_module.c", f"{name}.c"], parts=view.parts)
        interrupts.check()  # a signal whose exception was swallowed (CasADi) never lets a build replace its output
        with output_errors(out_dir):
            if build_key is not None:
                cache.record(staging, build_key)
            _swap_in(staging, out_dir, inputs)
    except BaseException:
        _remove(staging)
        raise
    return out_dir


def _check_replaceable(out_dir: Path, inputs: tuple[Path, ...], locked: bool = False) -> None:
    with nullcontext() if locked else parent_locked(out_dir, shared=True):
        problem = replace_problem(out_dir, inputs)
    if problem:
        raise OutputError(problem)


_signals_held = interrupts.held  # the swap's signals wait for its end


@contextmanager
def parent_locked(out_dir: Path, shared: bool = False) -> Iterator[None]:
    """A lock on the output's parent directory (POSIX flock): exclusive, so that builds to one
    output directory running at once swap in one after the other (the last one wins, whole);
    shared, to read the output while no swap is half done (between its two renames the
    directory is absent, and its files would look foreign). No parent yet: nothing to lock."""
    if fcntl is None or not out_dir.parent.is_dir():  # not POSIX, or nothing there yet
        yield
        return
    fd = os.open(out_dir.parent, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _swap_in(staging: Path, out_dir: Path, inputs: tuple[Path, ...]) -> None:
    """Renames the staging directory to ``out_dir``, the earlier output aside and then away,
    under the lock and with signals held. The earlier output is checked again first (files may
    have come into it during the build), and of it only what robotgen can prove it wrote is
    deleted: anything that came in between that check and the rename is kept aside, and said."""
    with parent_locked(out_dir), _signals_held():
        _check_replaceable(out_dir, inputs, locked=True)
        if not out_dir.exists():
            staging.rename(out_dir)
            return
        previous = sibling(out_dir, "old")
        out_dir.rename(previous)
        try:
            staging.rename(out_dir)
        except BaseException:
            previous.rename(out_dir)
            raise
        left = remove_written(previous)
    if left:
        print(
            f"robotgen: warning: {', '.join(left)} came into {out_dir} during the build; kept in {previous}",
            file=sys.stderr,
        )


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
