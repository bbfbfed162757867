"""The resolved motion maps of a spherical-wrist arm by two 3 x 3 solves at the wrist centre
(symbolic/rigid_body/inverse_jacobian.py) against numpy's 6 x 6 solve of the chain's own
hand Jacobian and Jdot qd (Newton-Euler's forward pass); the singular neighbourhoods against
Hadamard's ratio computed from J alone (tests/reference.py); Table 1's counts. Graphs are
evaluated with CasADi (what the C is printed from)."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import yaml
from reference import hadamard_ratios, wrist_centre_blocks
from scipy.optimize import brentq

from robotgen.frontend import load_system
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.inverse_jacobian import SINGULAR_DETERMINANT
from robotgen.symbolic.root_laws.hand import Hand, checked_solve
from robotgen.symbolic.root_laws.resolved_adaptive import stage_counts

ROOT = Path(__file__).resolve().parents[2]
PUMA, RMAC = ROOT / "specs" / "puma560.yaml", ROOT / "specs" / "puma560_rmac.yaml"


def rmac_hand() -> Hand:
    system = load_system(str(RMAC))
    return Hand(system.nodes[system.root_node.robot].leaf, system.root_node.hand.tool)


def general_hand(tmp_path) -> Hand:
    """A member of the family with nothing of the PUMA's special geometry: axis 1 tilted 60
    degrees to axis 2 and 0.1 m from it, off the base origin, axis 6 perpendicular to axis 4
    at q = 0, a tool turned and moved off axis 6."""
    data = yaml.safe_load(PUMA.read_text())
    data["name"] = "general_elbow"
    chain = data["nodes"]["arm"]["define"]["chain"]
    chain.update(
        base={"xyz": [0.2, -0.1, 0.5], "rpy": [0.3, -0.2, 0.1]},
        tool={"xyz": [0.01, 0.02, 0.1], "rpy": [0.4, 0.5, -0.6]},
    )
    for i, dh in {0: {"a": 0.1, "alpha": "pi/3", "d": 0.3}, 4: {"theta": "pi/2"}, 5: {"d": 0.05}}.items():
        chain["joints"][i]["dh"].update(dh)
    path = tmp_path / "general_elbow.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return Hand(load_system(str(path)).nodes["arm"].leaf, np.eye(4))


class Maps:
    """J, Jdot qd and the two resolved motion maps of one hand as CasADi Functions."""

    def __init__(self, hand: Hand):
        assert hand.wrist_centre is not None
        q, qd, twist, accel = (ca.SX.sym(s, 6) for s in ("q", "qd", "twist", "accel"))
        self.J = ca.Function("J", [q], [hand.jacobian(q)])
        self.bias = ca.Function("bias", [q, qd], [hand.bias(q, qd)])
        self.rates = ca.Function("rates", [q, twist], [hand.joint_rates(q, twist)])
        self.accelerations = ca.Function("accelerations", [q, qd, accel], [hand.joint_accelerations(q, qd, accel)])

    def __call__(self, q, qd, twist, accel) -> tuple[np.ndarray, ...]:
        return (
            np.array(self.J(q)),
            np.array(self.bias(q, qd)).ravel(),
            np.array(self.rates(q, twist)).ravel(),
            np.array(self.accelerations(q, qd, accel)).ravel(),
        )


@pytest.mark.parametrize("which", ["puma560_rmac", "general"])
def test_wrist_centre_solves_are_the_6x6_solve(which, tmp_path):
    """At 200 random states (J's condition number below 1e4), qd = J^-1 twist and
    qdd = J^-1 (accel - Jdot qd) agree with numpy's LU solve of the chain's J and Newton-Euler's
    Jdot qd to 1e-12 of their largest entry; J at the wrist centre is block lower triangular."""
    maps = Maps(rmac_hand() if which == "puma560_rmac" else general_hand(tmp_path))
    rng = np.random.default_rng(11)
    worst = worst_block = 0.0
    kept = 0
    for _ in range(200):
        q, qd, twist, accel = rng.uniform(-np.pi, np.pi, 6), rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
        J, bias, rates, accelerations = maps(q, qd, twist, accel)
        if np.linalg.cond(J) > 1e4:
            continue
        kept += 1
        worst_block = max(worst_block, np.abs(wrist_centre_blocks(J)[1]).max() / np.abs(J).max())
        for mine, theirs in ((rates, np.linalg.solve(J, twist)), (accelerations, np.linalg.solve(J, accel - bias))):
            worst = max(worst, np.abs(mine - theirs).max() / np.abs(theirs).max())
    print(f"\n  {which}: {kept} states, worst relative difference {worst:.1e}, |J12| / |J| {worst_block:.1e}")
    assert kept > 150 and worst < 1e-12 and worst_block < 1e-14


POSE = np.array([0.3, 0.5, -0.4, 0.7, 0.8, -1.1])
# (joint moved from POSE, an interval holding one singular value of it, the block it makes
# singular (0: J11, 1: J22), the half-width of the NaN neighbourhood in rad)
SINGULARITIES = {
    "wrist (q5 = 0)": (4, (-0.1, 0.1), 1, 1.000e-6),
    "elbow stretched (q3 = -1.5238)": (2, (-1.6, -1.45), 0, 2.04e-6),
    "shoulder: wrist centre over axis 1 (q2 = 1.0085)": (1, (0.9, 1.1), 0, 3.85e-7),
}


def neighbourhood(maps: Maps, pose: np.ndarray, joint: int, bracket: tuple[float, float], block: int) -> tuple:
    """The singular value of ``joint`` in ``bracket`` (where det of the block changes sign)
    with the others at ``pose``, and the edges of its NaN neighbourhood below and above (where
    the block's Hadamard ratio is SINGULAR_DETERMINANT), from numpy on J alone; checks that
    all six joint rates and accelerations are NaN at it and within 0.9 of the edges, finite
    at 1.1 and 10 times them."""
    qd, twist, accel = np.array([0.2, -0.1, 0.3, 0.5, -0.4, 0.6]), np.linspace(-1, 1, 6), np.linspace(2, -1, 6)

    def at(x):
        q = pose.copy()
        q[joint] = x
        return q

    def det(x):
        J11, _, J22, _ = wrist_centre_blocks(np.array(maps.J(at(x))))
        return np.linalg.det((J11, J22)[block])

    singular = brentq(det, *bracket, xtol=1e-15)
    edges = [
        brentq(
            lambda d, side=side: (
                hadamard_ratios(np.array(maps.J(at(singular + side * d))))[block] - SINGULAR_DETERMINANT
            ),
            1e-10,
            1e-3,
            xtol=1e-16,
        )
        for side in (-1, 1)
    ]
    for side, edge in zip((-1, 1), edges):
        for x, expect_nan in ((0, True), (0.9 * edge, True), (1.1 * edge, False), (10 * edge, False)):
            _, _, rates, accelerations = maps(at(singular + side * x), qd, twist, accel)
            for values in (rates, accelerations):
                assert np.isnan(values).all() if expect_nan else np.isfinite(values).all(), (x, values)
    return singular, edges


@pytest.mark.parametrize("name", SINGULARITIES)
def test_nan_exactly_near_each_singularity(name):
    """NaN in all six joint rates and accelerations where a block's |det| is below 1e-6 of
    Hadamard's bound (the product of its column norms), finite beyond: on the PUMA 560 of
    puma560_rmac at POSE, within 1.0e-6 rad of q5 = 0 (|sin q5| < 1e-6, J22's columns being
    unit), 2.04e-6 rad of the stretched elbow and 3.85e-7 rad (in q2) of the wrist centre
    over axis 1."""
    joint, bracket, block, half_width = SINGULARITIES[name]
    singular, edges = neighbourhood(Maps(rmac_hand()), POSE, joint, bracket, block)
    print(f"\n  {name}: singular at {singular:.6f}, NaN within {edges[0]:.3g} below and {edges[1]:.3g} above")
    for edge in edges:
        assert abs(edge / half_width - 1) < 0.01


def test_nan_near_the_singularities_of_a_general_member(tmp_path):
    """The same on the general member (axis 1 tilted and offset, axis 6 at 90 degrees to
    axis 4 at q = 0, a tool off axis 6): every singular value of q2, q3 (J11) and q5 (J22)
    on a grid over (-pi, pi] at a random pose."""
    maps = Maps(general_hand(tmp_path))
    pose = np.random.default_rng(12).uniform(-np.pi, np.pi, 6)
    grid = np.linspace(-np.pi, np.pi, 181)
    found = 0
    for joint, block in ((1, 0), (2, 0), (4, 1)):
        dets = []
        for x in grid:
            q = pose.copy()
            q[joint] = x
            J11, _, J22, _ = wrist_centre_blocks(np.array(maps.J(q)))
            dets.append(np.linalg.det((J11, J22)[block]))
        for k in np.flatnonzero(np.sign(dets[:-1]) != np.sign(dets[1:])):
            neighbourhood(maps, pose, joint, (grid[k], grid[k + 1]), block)
            found += 1
    assert found >= 5  # q5: two; q3: stretched and folded; q2: at least one


def test_stages_2_and_3_cost_less_than_the_paper():
    """Table 1's stages 2 (eq 11) and 3 (eq 13, what it adds to stage 2: the exact Jdot qd
    and the second solve, stage 2's factor reused) below Lee and Lee's multiplications and
    additions on the PUMA 560, and stage 2 below a quarter of the 6 x 6 Householder solve's
    operations; stage 1 (the inverse kinematics) within the paper's multiplications."""
    rows = {r["name"]: r for r in stage_counts(load_system(str(RMAC)))["rows"]}
    for name in ("joint rates (eq 11)", "joint accelerations (eq 13)"):
        ours, paper = rows[name]["robotgen"], rows[name]["paper"]
        print(f"\n  {name}: {ours} against the paper's {paper}")
        assert ours["mul"] < paper["mul"] and ours["add"] < paper["add"]
    ik = rows["inverse kinematics"]
    assert ik["robotgen"]["mul"] <= ik["paper"]["mul"]  # its additions: docs/spec-format.md
    hand = rmac_hand()
    q, twist = ca.SX.sym("q", 6), ca.SX.sym("twist", 6)
    general = count_operations([q, twist], [checked_solve(hand.jacobian(q), twist)])
    assert rows["joint rates (eq 11)"]["robotgen"]["total"] < general["total"] / 4
