"""What robotgen may delete or replace in an output directory: only files whose content it
can prove it wrote (docs/cli.md, "The output directory"). A build's directory is proven by
its manifest.json (robotgen.emit.output_directory); `simulate`, which writes its CSV and PNG
into a directory that may hold anything else, keeps a record of the sha256 of each file it
wrote there (``RECORD``) and replaces a file only when its content has one of them. A file
the record does not vouch for, a directory, a symbolic link, or an input of the command
(the spec) is never touched: the command stops with exit status 1 and names it.

Errors of the output directory itself (a path through a regular file, a name too long, no
permission, an immutable directory) are the user's to fix: OutputError, exit status 1."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import secrets
import stat
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from robotgen import interrupts
from robotgen.errors import OutputError

RECORD = ".robotgen-files"
# A file robotgen wrote is at most this large (the largest C source of a 32-joint tree is
# 0.6 MB, an extension a few MB); a larger one is not hashed, and so not proven.
MAX_PROVEN_BYTES = 256 << 20


def sha256_of(path: Path) -> str | None:
    """The sha256 of a regular file (not a symbolic link) of at most MAX_PROVEN_BYTES, else None."""
    try:
        info = path.lstat()
        if not stat.S_ISREG(info.st_mode) or info.st_size > MAX_PROVEN_BYTES:
            return None
        digest = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        return digest.hexdigest()
    except OSError:
        return None


def shown(names: list[str]) -> str:
    """Up to five names, then how many more."""
    return ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")


def refusal(directory: Path, foreign: list[str], changed: list[str], what: str) -> str | None:
    """The message for files robotgen did not write (``foreign``) or that changed since it
    wrote them (``changed``), which it refuses to ``what`` ("replace it"), or None."""
    parts = ([f"files that robotgen did not write ({shown(foreign)})"] if foreign else []) + (
        [f"files that changed since robotgen wrote them ({shown(changed)})"] if changed else []
    )
    if not parts:
        return None
    return (
        f"{directory} holds {' and '.join(parts)}; refusing to {what} (move them, or choose another output directory)"
    )


def input_inside(directory: Path, inputs: Iterable[Path], names: Iterable[str] | None = None) -> str | None:
    """An input of the command (the spec, a URDF it reads) inside ``directory`` (or, with
    ``names``, standing at one of those names in it), as a message, or None."""
    try:
        root = directory.resolve()
        targets = None if names is None else {(directory / n).resolve() for n in names}
        for path in inputs:
            real = Path(path).resolve()
            if (real in targets) if targets is not None else real.is_relative_to(root):
                return (
                    f"{directory} holds {path}, which this command reads; robotgen never replaces its input "
                    "(choose another output directory)"
                )
    except (OSError, RuntimeError):  # a symlink loop: nothing to compare
        return None
    return None


@contextmanager
def output_errors(directory: Path) -> Iterator[None]:
    """OSErrors of writing ``directory`` as the user's OutputError naming the path: a path
    through a regular file (NotADirectoryError, or FileExistsError from making a directory
    where a file is), a name too long, no permission, an immutable or read-only directory."""
    try:
        yield
    except OSError as error:
        blocking = _file_on_the_way(Path(directory))
        if blocking is not None and error.errno in (errno.ENOTDIR, errno.EEXIST):
            reason = f"{blocking} is a file, not a directory"
        else:
            reason = error.strerror or str(error)
            if error.filename is not None and not str(error.filename).startswith(str(directory)):
                reason += f" ({error.filename})"
        raise OutputError(f"cannot write the output directory {directory}: {reason}") from None


def _file_on_the_way(path: Path) -> Path | None:
    """The first part of ``path`` that exists and is not a directory."""
    for part in [*reversed(path.parents), path]:
        try:
            if os.path.lexists(part) and not part.is_dir():
                return part
        except OSError:
            return None
    return None


def sibling(path: Path, kind: str) -> Path:
    """An unused hidden name beside ``path``: .<name>.<kind>-<pid>-<random>."""
    while True:
        candidate = path.parent / f".{path.name}.{kind}-{os.getpid()}-{secrets.token_hex(4)}"
        if not os.path.lexists(candidate):
            return candidate


# -- simulate's files: a record of what robotgen wrote into a directory of the user's ---------------
def _record(directory: Path) -> tuple[dict[str, list[str]] | None, str | None]:
    """(file name -> the sha256 robotgen wrote it with, a problem): an absent record is empty."""
    path = directory / RECORD
    if not os.path.lexists(path):
        return {}, None
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > 1 << 20:
            raise ValueError
        files = json.loads(path.read_text(encoding="utf-8"))["files"]
        if not isinstance(files, dict) or not all(
            isinstance(k, str) and isinstance(v, list) and all(isinstance(h, str) for h in v) for k, v in files.items()
        ):
            raise ValueError
        return files, None
    except (OSError, ValueError, KeyError, TypeError):
        return None, f"{directory} holds {RECORD}, which robotgen did not write; refusing to write there"


def write_problem(directory: Path, names: list[str], inputs: Iterable[Path] = ()) -> str | None:
    """Why robotgen may not write ``names`` into ``directory`` (replacing files of those names
    that it cannot prove it wrote, or an input), or None. OSErrors are the caller's."""
    if os.path.lexists(directory) and not directory.is_dir():
        return f"{directory} exists and is not a directory"
    if not directory.exists():
        return None
    problem = input_inside(directory, inputs, names)
    if problem:
        return problem
    record, problem = _record(directory)
    if problem or record is None:  # (a record is read, or there is a problem)
        return problem
    foreign, changed = [], []
    for name in names:
        path = directory / name
        if not os.path.lexists(path):
            continue
        digest = sha256_of(path)
        if digest is None or name not in record:
            foreign.append(name)
        elif digest not in record[name]:
            changed.append(name)
    return refusal(directory, foreign, changed, "overwrite them")


def write_files(directory: Path, made: dict[str, Path], inputs: Iterable[Path] = ()) -> None:
    """Puts each made file (name -> where it was made) into ``directory`` under its name,
    replacing only what ``write_problem`` allows (checked again here). The record first lists
    the new sha256 beside the old one, then each file is replaced whole (a copy beside it,
    renamed over it), then the record keeps the new one only: interrupted anywhere, every
    file there is one the record vouches for. Signals wait until the files are in place."""
    with output_errors(directory):
        directory.mkdir(parents=True, exist_ok=True)
        with interrupts.held():
            problem = write_problem(directory, list(made), inputs)
            if problem:
                raise OutputError(problem)
            record = _record(directory)[0] or {}  # (write_problem read it)
            new: dict[str, str] = {}
            for name, path in made.items():
                digest = sha256_of(path)
                if digest is None:
                    raise OutputError(f"{path} is not a regular file robotgen made")
                new[name] = digest
            _write_record(directory, {**record, **{n: [*record.get(n, []), h] for n, h in new.items()}})
            for name, path in made.items():
                temporary = sibling(directory / name, "tmp")
                try:
                    temporary.write_bytes(path.read_bytes())
                    os.replace(temporary, directory / name)
                finally:
                    if os.path.lexists(temporary):
                        temporary.unlink()
            _write_record(directory, {**record, **{n: [h] for n, h in new.items()}})


def _write_record(directory: Path, files: dict[str, list[str]]) -> None:
    temporary = sibling(directory / RECORD, "tmp")
    try:
        temporary.write_text(json.dumps({"files": files}, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(temporary, directory / RECORD)
    finally:
        if os.path.lexists(temporary):
            temporary.unlink()
