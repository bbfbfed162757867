"""Regrouped inertial parameters: the zeros they promise, a closed form on the planar two-link
arm, the same M, C and torques as the bodies' own parameters on real robots and on a branched
tree with a prismatic joint and oblique axes, and fewer operations."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from robots import PANDA, UR5, robots_dir
from test_tree_pinocchio import random_tree, with_coordinate_axes

from robotgen.frontend.urdf import read_urdf
from robotgen.model.chain import Body, Joint, KinematicTree
from robotgen.model.regrouping import origin_parameters, regrouped_inertias
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.coriolis import coriolis_spatial
from robotgen.symbolic.rigid_body.crba import crba
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.rnea import rnea


def urdf_tree(which) -> KinematicTree:
    return read_urdf(str(robots_dir() / which[0]), which[1]).tree


def test_the_promised_zeros():
    """About coordinate axis k: no mass, no first moment along k, and the inertia entry of axis
    k + 2 (mod 3) removed; a prismatic joint's body keeps no rotational inertia."""
    tree = with_coordinate_axes(random_tree(0))
    params = regrouped_inertias(tree)
    for joint, p in zip(tree.joints, params):
        if joint.type == "prismatic":
            assert not p.inertia.any() and p.mass >= joint.body.mass > 0
            continue
        k = int(np.flatnonzero(joint.axis)[0])
        u = (k + 2) % 3
        assert p.mass == 0.0 and p.first_moment[k] == 0.0 and p.inertia[u, u] == 0.0
        others = [i for i in range(3) if i != k]
        assert np.count_nonzero(p.first_moment[others]) == 2  # what stays is not zero by accident


def test_planar_two_link_closed_form():
    """Two links about parallel z axes, the second at distance a along the first's x: the first
    keeps ZZ1 + m2 a^2 about its axis (plus terms no torque reads), the second m = 0,
    h = m2 (cx, cy, 0), XX - YY and its own ZZ."""
    a, m1, m2 = 0.7, 2.0, 1.5
    c1, c2 = np.array([0.3, 0.05, 0.1]), np.array([0.25, -0.04, 0.2])
    I1, I2 = np.diag([0.02, 0.03, 0.04]), np.diag([0.05, 0.06, 0.07])

    def joint(i, parent, x, m, c, Ic):
        origin = np.eye(4)
        origin[0, 3] = x
        return Joint(f"j{i}", "revolute", parent, origin, np.array([0.0, 0.0, 1.0]), Body(m, c, Ic))

    tree = KinematicTree(
        "two", (joint(0, -1, 0.0, m1, c1, I1), joint(1, 0, a, m2, c2, I2)), 1, np.eye(4), np.array([0.0, -9.81, 0.0])
    )
    p1, p2 = regrouped_inertias(tree)
    bar2 = I2 + m2 * (c2 @ c2 * np.eye(3) - np.outer(c2, c2))  # about joint 2's origin
    bar1 = I1 + m1 * (c1 @ c1 * np.eye(3) - np.outer(c1, c1))
    assert p2.mass == 0.0
    np.testing.assert_allclose(p2.first_moment, [m2 * c2[0], m2 * c2[1], 0.0], rtol=1e-15)
    np.testing.assert_allclose(np.diag(p2.inertia), [bar2[0, 0] - bar2[1, 1], 0.0, bar2[2, 2]], rtol=1e-15)
    assert p1.mass == 0.0
    assert p1.inertia[2, 2] == pytest.approx(bar1[2, 2] + m2 * a * a, rel=1e-15)
    assert p1.inertia[1, 1] == 0.0


def graphs_both_ways(tree: KinematicTree):
    n = tree.nq
    sym = Symbols.make(n)
    g = ChainGraphs(tree, sym)
    own = [OriginInertia.constant(origin_parameters(j.body)) for j in g.tree.joints]
    return g, sym, own


@pytest.mark.parametrize("which", ["ur5", "panda", "coordinate_axes_tree", "oblique_tree"])
def test_same_dynamics_as_the_bodies_own_parameters(which):
    tree = {
        "ur5": lambda: urdf_tree(UR5),
        "panda": lambda: urdf_tree(PANDA),
        "coordinate_axes_tree": lambda: with_coordinate_axes(random_tree(1)),
        "oblique_tree": lambda: random_tree(2),
    }[which]()
    g, s, own = graphs_both_ways(tree)
    regrouped = g.inertias
    outs = []
    for inertias in (own, regrouped):
        outs += [
            crba(g.tree, g.motions, inertias),
            rnea(g.tree, g.motions, inertias, s.qd, s.qdd),
            coriolis_spatial(g.tree, g.motions, inertias, s.qd),
        ]
    f = ca.Function("f", [s.q, s.qd, s.qdd], outs)
    rng = np.random.default_rng(7)
    for _ in range(20):
        values = [np.array(v) for v in f(*rng.normal(size=(3, tree.nq)))]
        for mine, theirs in zip(values[3:], values[:3]):
            np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12 * max(1.0, np.abs(theirs).max()))


def test_fewer_operations_on_real_arms():
    """Inverse dynamics and M with regrouped parameters against the bodies' own (last measured:
    UR5 ID 319 against 407 and M 209 against 232; Panda 660 against 779, 434 against 467)."""
    for which in (UR5, PANDA):
        g, s, own = graphs_both_ways(urdf_tree(which))
        counts = {}
        for label, inertias in (("own", own), ("regrouped", g.inertias)):
            counts[label] = [
                count_operations([s.q, s.qd, s.qdd], [e])["total"]
                for e in (rnea(g.tree, g.motions, inertias, s.qd, s.qdd), crba(g.tree, g.motions, inertias))
            ]
        assert counts["regrouped"][0] < 0.9 * counts["own"][0], (which, counts)
        assert counts["regrouped"][1] < counts["own"][1], (which, counts)
