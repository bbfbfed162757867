"""DEFINE's attributes (Deno et al. 1990, §3.2) for every kind of leaf, in one shape:
M(q), C(q, qd), N(q, qd), and the kinematic output map an ATTACH frame change uses."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.system import PLANAR_OUTPUT, PlanarBody, SpatialBody
from robotgen.symbolic.formulas import FormulaGraphs, expression_map
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.christoffel import coriolis_matrix
from robotgen.symbolic.rigid_body.rpy import rpy_rate_map, rpy_rotation
from robotgen.symbolic.rigid_body.spatial import const


@dataclass(frozen=True, eq=False)
class LeafAttributes:
    """A leaf's M, C, N and its kinematics (output kind -> x(q)) and inverse kinematics, as SX."""

    M: ca.SX
    C: ca.SX
    N: ca.SX
    kinematics: Callable[[str], ca.SX] | None  # output kind -> x = f(q)
    inverse_kinematics: Callable[[ca.SX], ca.SX] | None  # x -> q


def leaf_attributes(leaf, q: ca.SX, qd: ca.SX, values: Mapping[str, ca.SX] | None = None) -> LeafAttributes:
    """M, C, N (and kinematics) of a leaf at (q, qd). ``values``: the leaf's run-time
    parameters as symbols, by their name in the leaf (a formulas parameter, a payload's
    "mass"); the others are folded."""
    values = dict(values or {})
    n = q.shape[0]
    sym = Symbols(q, qd, ca.SX.zeros(n), ca.SX.zeros(n))
    if isinstance(leaf, KinematicTree):
        g = ChainGraphs(leaf, sym)

        def tip(output: str) -> ca.SX:
            p = g.fk()[:3, 3]
            return p[:2] if output == PLANAR_OUTPUT else p

        return LeafAttributes(g.mass(), g.coriolis(), g.gravity() + g.friction(), tip, None)
    if isinstance(leaf, FormulaRobot):
        fg = FormulaGraphs(leaf, sym, values)
        kin = (lambda output: fg.kinematics()) if leaf.kinematics else None
        ik = (
            expression_map(leaf.inverse_kinematics, leaf.outputs, {**leaf.parameters, **values})
            if leaf.inverse_kinematics
            else None
        )
        return LeafAttributes(fg.mass(), fg.coriolis(), fg.n_term(qd), kin, ik)
    if isinstance(leaf, PlanarBody):
        if "mass" in values:
            m = values["mass"]
            M = ca.diag(ca.vertcat(m, m, leaf.inertia))
            N = ca.vertcat(-m * leaf.gravity[0], -m * leaf.gravity[1], 0)
        else:
            M = ca.SX(ca.DM(ca.diag(ca.DM([leaf.mass, leaf.mass, leaf.inertia]))))
            N = ca.SX(ca.DM([-leaf.mass * leaf.gravity[0], -leaf.mass * leaf.gravity[1], 0.0]))
        return LeafAttributes(M, ca.SX.zeros(3, 3), N, None, None)
    if isinstance(leaf, SpatialBody):
        R, E = rpy_rotation(q[3:6]), rpy_rate_map(q[3:6])
        RE = R.T @ E  # body-frame angular velocity per rpy rate
        mass: ca.SX | float = values["mass"] if "mass" in values else leaf.mass
        M = ca.diagcat(mass * ca.SX.eye(3), RE.T @ const(leaf.inertia) @ RE)
        N = ca.vertcat(
            -mass * const(leaf.gravity) if "mass" in values else const(-leaf.mass * leaf.gravity), ca.SX.zeros(3, 1)
        )
        return LeafAttributes(M, coriolis_matrix(M, q, qd), N, None, None)
    raise TypeError(f"unknown leaf type {type(leaf).__name__}")
