"""Progress of a long build on stderr: stages, and kernels as they are printed to C. Shown
when stderr is a terminal (or ROBOTGEN_PROGRESS=1 asks for it, e.g. in a CI log), never with
`-q`; never on stdout, which carries only results."""

from __future__ import annotations

import os
import sys
import time


class Progress:
    """Progress of a build on stderr: each stage with the seconds since the start, when enabled."""

    def __init__(self, enabled: bool = True, stream=None):
        self.enabled = enabled
        self.stream = stream
        self.started = time.monotonic()

    def stage(self, text: str) -> None:
        """Print a stage's line, with the seconds since the start."""
        if self.enabled:
            stream = self.stream or sys.stderr
            print(f"robotgen: [{time.monotonic() - self.started:5.1f} s] {text}", file=stream, flush=True)

    def step(self, index: int, total: int, text: str) -> None:
        """Item ``index`` (1-based) of ``total``; only a few lines for long lists."""
        every = max(1, total // 8)
        if index == 1 or index == total or index % every == 0:
            self.stage(f"{text} ({index}/{total})")


QUIET = Progress(enabled=False)


def for_terminal(quiet: bool) -> Progress:
    """On when stderr is a terminal or ROBOTGEN_PROGRESS=1, off with -q."""
    wanted = os.environ.get("ROBOTGEN_PROGRESS") == "1" or sys.stderr.isatty()
    return Progress(enabled=wanted and not quiet)
