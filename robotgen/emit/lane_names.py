"""The C names through which one printing of a kernel's lanes serves every vector width.

A lane kernel (robotgen.emit.lanes) is rendered once, in these names, and ``<name>.c`` holds
a copy for each width: before each copy it defines them for that width (the vector type, its
number of lanes, a broadcast, the instruction set the copy is compiled for, and a suffix that
keeps each copy's functions apart)."""

from __future__ import annotations

VECTOR = "rg_v"  # W values of the module's type (GCC/Clang vector extension)
MASK_VECTOR = "rg_vm"  # what comparing two rg_v gives: W integers of the type's size, all ones or zero
WIDTH = "RG_W"  # W, the number of lanes
SPLAT = "RG_SPLAT"  # RG_SPLAT(x): x in every lane
TARGET = "RG_TARGET"  # __attribute__((target("avx2"))), or nothing
PER_WIDTH = "RG_L"  # RG_L(name): the name of this width's copy
LANE_INDEX = "rg_l"  # the loop over lanes of an operation printed lane by lane


def per_width(name: str) -> str:
    """``name`` as this width's copy names it."""
    return f"{PER_WIDTH}({name})"


def splat(value: str) -> str:
    """A scalar ``value`` broadcast to every lane."""
    return f"{SPLAT}({value})"
