"""python -m robotgen, and the robotgen command: the command line (robotgen.cli).

robotgen.cli imports numpy and CasADi, which takes a moment; a Ctrl-C or SIGTERM that lands
meanwhile is held until the import is done (raised inside a C extension's import it would
surface as an ImportError traceback), then answered as robotgen answers it later: one line,
exit 130 or 143, nothing done. A Ctrl-C between the handlers' return and robotgen.cli.entry's
own handling is answered the same way."""

import signal
import sys


def main() -> None:
    """`python -m robotgen`: the command line, a Ctrl-C before it has set its own handlers ends with status 130."""
    try:
        _start()
    except KeyboardInterrupt:
        sys.stderr.write("robotgen: interrupted\n")
        sys.exit(130)


def _start() -> None:
    held: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: held.append(signum)) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        from robotgen.cli import entry
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if held:
        interrupted = held[0] == signal.SIGINT
        sys.stderr.write("robotgen: interrupted\n" if interrupted else "robotgen: terminated\n")
        sys.exit(130 if interrupted else 143)
    entry()


if __name__ == "__main__":
    main()
