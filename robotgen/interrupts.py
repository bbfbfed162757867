"""SIGINT and SIGTERM during a command: noted when they arrive, so that none is lost.

Python runs a signal's handler in the main thread between two bytecodes (or inside
PyErr_CheckSignals), and the handler's exception (KeyboardInterrupt for SIGINT) propagates
from there. CasADi's argument conversion (its SWIG typemaps, on every SX operation) calls back
into Python (an operand's ``shape`` property) and clears the error it meets there while it
tries the next conversion: a KeyboardInterrupt raised in that window vanished and the build
went on to replace its output (6 of 24 SIGINTs sent while the PUMA 560's graphs were built,
in process). So the handlers here note the signal before they raise its exception, and
``check()`` raises it again where a command would otherwise go on: before an output is
swapped in, after each stage, and when the command ends."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager


class Terminated(BaseException):
    """SIGTERM, raised where the process is, so that a build cleans up as it does on Ctrl-C."""


_noted: list[int] = []


def exception_for(signum: int) -> BaseException:
    """The exception a signal is raised as: KeyboardInterrupt for SIGINT, Terminated for SIGTERM."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


def answer(signum: int, frame) -> None:
    """The handler: note the signal, then raise its exception."""
    _noted.append(signum)
    raise exception_for(signum)


def check() -> None:
    """Raises the exception of a signal answered since the command began (again, if it was
    raised once and swallowed)."""
    if _noted:
        raise exception_for(_noted[0])


def answer_both() -> None:
    """SIGTERM and SIGINT answered by ``answer`` for the life of the process (the robotgen
    command): SIGINT unless it is ignored (a background job), or handled by someone else."""
    signal.signal(signal.SIGTERM, answer)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, answer)


@contextmanager
def noting() -> Iterator[None]:
    """A command's extent: signals are noted from its start to its end (and forgotten
    after, so that a later build in the same process is not stopped by them), and in the
    main thread SIGINT is answered by ``answer`` where Python's default handler would raise
    KeyboardInterrupt (robotgen called in process); SIGTERM only where the robotgen command
    set ``answer`` for it. The handlers of before are put back afterwards."""
    _noted.clear()
    main = threading.current_thread() is threading.main_thread()
    before = signal.getsignal(signal.SIGINT) if main else None
    if main and before is signal.default_int_handler:
        signal.signal(signal.SIGINT, answer)
    try:
        yield
    finally:
        if main and before is signal.default_int_handler:
            signal.signal(signal.SIGINT, before)
        _noted.clear()


@contextmanager
def held() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block is left: the renames of a swap and the removal
    of the old output happen whole, so an output is never missing and nothing is left beside
    it. Python runs signal handlers in the main thread, between bytecodes, but the signal
    itself may reach any thread (OpenBLAS's among them), so masking it in this one is not
    enough: until the block is left the handlers only note the signal, which is then raised
    again under the handlers of before."""
    signals = (signal.SIGINT, signal.SIGTERM)
    if threading.current_thread() is not threading.main_thread() or None in map(signal.getsignal, signals):
        yield  # the handlers raise in the main thread only; None: a handler not set from Python
        return
    waiting: list[int] = []
    before = {signum: signal.signal(signum, lambda received, frame: waiting.append(received)) for signum in signals}
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
        if waiting:
            signal.raise_signal(waiting[0])
