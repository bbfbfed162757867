"""Errors that are the user's fault carry a location; everything else is a robotgen bug."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Location:
    """1-based line and column in a user's file."""

    file: str
    line: int = 1
    col: int = 1

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class UserError(Exception):
    """The user's input is wrong: reported as FILE:LINE:COL: message, exit status 1."""

    def __init__(self, location: Location, message: str):
        super().__init__(f"{location}: {message}")
        self.location = location
        self.message = message


class UserErrors(Exception):
    """Several user errors found in one pass (a spec is checked whole before reporting)."""

    def __init__(self, errors: list[UserError]):
        super().__init__("\n".join(str(e) for e in errors))
        self.errors = errors


class MissingDependency(Exception):
    """An optional package that the input needs is not installed (MuJoCo for an MJCF file):
    the user's setup, exit status 1, the message says what to install."""


MUJOCO_INSTALL = "pip install 'robotgen[mujoco]'"  # what MuJoCo's messages tell a user to run


class OutputError(Exception):
    """An output directory robotgen may not or cannot write: it holds files robotgen cannot
    prove it wrote, or the system refuses it (a path through a regular file, a name too long,
    no permission). The user's to fix: exit status 1, the message names the path."""
