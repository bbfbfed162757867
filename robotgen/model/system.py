"""A robot system: a tree of primitive nodes (Deno et al. 1990, ch. 3). The spine has
DEFINE leaves only; ATTACH and CONTROL nodes join the tree in later versions."""
from __future__ import annotations

from dataclasses import dataclass

from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot

Leaf = KinematicTree | FormulaRobot


@dataclass(frozen=True, eq=False)
class DefineNode:
    """DEFINE(M, C, N, rd, wr): a leaf robot. rd/wr are the joint state and torque ports."""

    name: str
    leaf: Leaf

    @property
    def primitive(self) -> str:
        return "define"

    @property
    def nq(self) -> int:
        return self.leaf.nq

    @property
    def coordinates(self) -> tuple[str, ...]:
        if isinstance(self.leaf, FormulaRobot):
            return self.leaf.coordinates
        return tuple(j.name for j in self.leaf.joints)


@dataclass(frozen=True, eq=False)
class RobotSystem:
    name: str
    source: str  # path of the spec (or URDF) it came from
    source_sha256: str
    nodes: dict[str, DefineNode]
    root: str
    warnings: tuple[str, ...] = ()  # located, printed by the CLI; the system is still valid

    @property
    def root_node(self) -> DefineNode:
        return self.nodes[self.root]
