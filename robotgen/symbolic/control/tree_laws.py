"""The tree control laws by name: the symbolic part (a TreeLaw) of each law of
robotgen.model.laws.registry that is not a root law."""

from __future__ import annotations

from robotgen.model.laws.registry import LAWS
from robotgen.symbolic.control.law import TreeLaw


def tree_law(name: str) -> TreeLaw:
    """The TreeLaw of the law called ``name``."""
    return LAWS[name].part("kernels")
