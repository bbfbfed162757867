"""What the symbolic layer knows of one node of a robot system (Deno et al. 1990, ch. 3):
its positions and velocity in its own coordinates (rd), its attributes M, C, N, and for an
ATTACH the maps that carry a written trajectory down to its robots."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from robotgen.model.signature import Signature
from robotgen.symbolic.define import LeafAttributes


@dataclass(eq=False)
class AttachMaps:
    """What ATTACH needs to write down: children velocities w = A v (children in order, each
    [external; internal]), Adot, the force map D [F_e; F_m1; F_i1] -> children external
    forces (J^T G^+, K^T, J^T H^T: eqs 5.3, 5.9), and h^-1 if known."""

    A: ca.SX
    Adot: ca.SX
    D: ca.SX
    h_inverse: Callable[[ca.SX], ca.SX] | None
    n_created_motions: int
    n_created_forces: int
    J: ca.SX  # constraint rows x robot coordinates (eq 3.2)
    H: ca.SX  # internal-force rows, orthonormal, spanning null(G) (eq 2.4)


@dataclass(eq=False)
class NodeGraph:
    """A node's graphs: signature, positions x, velocity v = [external; internal motions], M, C, N, leaf or ATTACH
    maps."""

    name: str
    sig: Signature
    x: ca.SX  # external positions
    v: ca.SX  # velocity, [external; internal motions]
    M: ca.SX
    C: ca.SX
    N: ca.SX
    leaf: LeafAttributes | None = None
    attach: AttachMaps | None = None

    @property
    def maps(self) -> AttachMaps:
        """An ATTACH node's maps (a TypeError for another node)."""
        if self.attach is None:
            raise TypeError(f"'{self.name}' is no ATTACH node")
        return self.attach
