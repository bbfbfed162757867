"""Writes a generated module's directory atomically: all or nothing."""
from __future__ import annotations

import json
import os
import shutil
import signal
import sysconfig
import threading
from contextlib import contextmanager
from pathlib import Path

from robotgen import interrupts
from robotgen.emit import compile as compiler
from robotgen.emit.cache import BUILD_KEY
from robotgen.emit.context import module_view
from robotgen.emit.manifest import manifest_json
from robotgen.emit.render import render_all
from robotgen.emit.targets import measure as measure_target
from robotgen.progress import QUIET, Progress
from robotgen.symbolic.control.law import Controller
from robotgen.symbolic.kernel import Kernel

try:
    import fcntl
except ImportError:  # not POSIX
    fcntl = None

MANIFEST = "manifest.json"


def emit(out_dir: Path, name: str, kernels: list[Kernel], *, nq: int,
         precision: str = "double", compile: bool = True, extra_info: dict | None = None,
         spec_sha256: str = "", attributes: dict | None = None, progress: Progress = QUIET,
         controllers: list[Controller] | None = None, targets: tuple[str, ...] = ()) -> Path:
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
    function's code and stack bytes in the manifest."""
    out_dir = Path(out_dir)
    view = module_view(name, kernels, nq=nq, precision=precision, spec_sha256=spec_sha256,
                       extra_info=extra_info, attributes=attributes, progress=progress,
                       controllers=tuple(controllers or ()))
    sources = render_all(view)
    files = dict(sources)
    _check_replaceable(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    staging = out_dir.parent / f".{out_dir.name}.tmp-{os.getpid()}"
    _remove(staging)
    try:
        staging.mkdir()
        for file_name, text in files.items():
            (staging / file_name).write_bytes(text.encode("utf-8"))
        reports = {}
        for target in targets:
            progress.stage(f"compiling for {target}")
            reports[target] = measure_target(target, staging, name)
        (staging / MANIFEST).write_bytes(manifest_json(view, sources, reports).encode("utf-8"))
        if compile:
            progress.stage(f"compiling the extension ({' '.join(compiler.compiler())})")
            compiler.compile_extension(staging, name, [f"{name}_module.c", f"{name}.c"], parts=view.parts)
        interrupts.check()  # a signal whose exception was swallowed (CasADi) never lets a build replace its output
        _swap_in(staging, out_dir)
    except BaseException:
        _remove(staging)
        raise
    return out_dir


def replace_problem(out_dir: Path) -> str | None:
    """Why ``out_dir`` may not be replaced by a build, or None. Only a missing or empty
    directory, or an earlier robotgen output holding nothing but what that build wrote (its
    manifest lists it) and what its Makefile makes, is ever replaced; never the current
    directory or one that contains it."""
    out_dir = Path(out_dir)
    if out_dir.is_symlink() or (out_dir.exists() and not out_dir.is_dir()):
        return f"{out_dir} exists and is not a directory"
    if not out_dir.exists():
        return None
    here = Path.cwd().resolve()
    if out_dir.resolve() == here or out_dir.resolve() in here.parents:
        return f"{out_dir} is the current directory or contains it; choose an output directory below it"
    entries = sorted(p.name for p in out_dir.iterdir())
    if not entries:
        return None
    try:
        manifest = json.loads((out_dir / MANIFEST).read_text(encoding="utf-8"))
        name, listed = manifest["name"], set(manifest["files"])
        assert "robotgen_version" in manifest and isinstance(name, str)
    except (OSError, ValueError, KeyError, TypeError, AssertionError):
        return (f"{out_dir} is not empty and is not a robotgen output (no robotgen {MANIFEST}); "
                "refusing to replace it")
    ours = listed | {MANIFEST, BUILD_KEY, f"{name}{sysconfig.get_config_var('EXT_SUFFIX')}",
                     f"{name}.o", f"lib{name}.a", f"{name}.pc", f"{name}Config.cmake"}
    foreign = [e for e in entries if e not in ours]
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        return (f"{out_dir} holds files that robotgen did not write ({shown}); refusing to replace it "
                "(move them, or choose another output directory)")
    return None


def _check_replaceable(out_dir: Path) -> None:
    problem = replace_problem(out_dir)
    if problem:
        raise FileExistsError(problem)


@contextmanager
def _signals_held():
    """SIGINT and SIGTERM wait until the block is left: the two renames of a swap and the
    removal of the old output happen whole, so the output is never missing and nothing is
    left beside it. Python runs signal handlers in the main thread, between bytecodes, but the
    signal itself may reach any thread (OpenBLAS's among them), so masking it in this one is
    not enough: until the block is left the handlers only note the signal, which is then
    raised again under the handlers of before."""
    held = (signal.SIGINT, signal.SIGTERM)
    if threading.current_thread() is not threading.main_thread() or None in map(signal.getsignal, held):
        yield  # the handlers raise in the main thread only; None: a handler not set from Python
        return
    noted: list[int] = []
    before = {signum: signal.signal(signum, lambda received, frame: noted.append(received)) for signum in held}
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
        if noted:
            signal.raise_signal(noted[0])


@contextmanager
def _parent_locked(out_dir: Path):
    """An exclusive lock on the output's parent directory (POSIX flock), so that builds to one
    output directory running at once swap in one after the other: the last one wins, whole."""
    if fcntl is None:  # not POSIX: no lock
        yield
        return
    fd = os.open(out_dir.parent, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _swap_in(staging: Path, out_dir: Path) -> None:
    previous = out_dir.parent / f".{out_dir.name}.old-{os.getpid()}"
    with _parent_locked(out_dir), _signals_held():
        if not out_dir.exists():
            staging.rename(out_dir)
            return
        _remove(previous)
        out_dir.rename(previous)
        try:
            staging.rename(out_dir)
        except BaseException:
            previous.rename(out_dir)
            raise
        _remove(previous)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
