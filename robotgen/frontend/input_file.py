"""An input file (spec, URDF, MJCF) read with a bound: a regular file of at most a given size.

A device (/dev/zero, /dev/urandom), a FIFO, a directory or a file past the bound is refused
with a message at the file before anything is read whole: /dev/zero would otherwise be read
until memory runs out, and a FIFO's open or read would wait for a writer forever."""

from __future__ import annotations

import os
import stat

from robotgen.errors import Location, UserError

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)
_CHUNK = 1 << 20


def read_input(path: str, limit: int, what: str, hint: str = "") -> bytes:
    """The bytes of ``path``, a regular file of at most ``limit`` bytes; otherwise a UserError
    located at the file naming ``what`` ("spec", "URDF file"), with ``hint`` after the bound.
    The file is opened without blocking (opening a FIFO for reading waits for a writer) and
    checked on the open descriptor, so what is checked is what is read; the read itself
    stops one byte past the bound (a file that grows while it is read)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as error:
        raise UserError(Location(path), f"cannot read {what}: {error.strerror or error}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = next((name for test, name in _KINDS if test(info.st_mode)), "not a regular file")
            raise UserError(Location(path), f"{what} is {kind}; robotgen reads regular files only")
        if info.st_size > limit:
            raise UserError(Location(path), f"{what} is {info.st_size} bytes; robotgen reads at most {limit}{hint}")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(_CHUNK, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:  # it grew while it was read
            raise UserError(Location(path), f"{what} is more than {limit} bytes; robotgen reads at most {limit}{hint}")
        return b"".join(chunks)
    except OSError as error:
        raise UserError(Location(path), f"cannot read {what}: {error.strerror or error}") from None
    finally:
        os.close(fd)
