"""Closed-form inverse kinematics of the PUMA 560 family (symbolic/rigid_body/spherical_wrist.py)
against forward kinematics: the eight solutions of random reachable poses, the branch chosen
by q_near, unwrapping past +-pi, the singular and unreachable cases; which arms belong to
the family; and the adaptive controller built around it. Graphs are evaluated with CasADi
(what the C is printed from), the last test through the compiled module."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import yaml
from robots import UR5, robots_dir

from robotgen.frontend import load_system
from robotgen.frontend.urdf import read_urdf
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.spherical_wrist import spherical_wrist_arm
from robotgen.symbolic.root_laws.hand import Hand
from robotgen.symbolic.root_laws.resolved_adaptive import StateLayout, stage_counts

ROOT = Path(__file__).resolve().parents[2]
PUMA, RMAC = ROOT / "specs" / "puma560.yaml", ROOT / "specs" / "puma560_rmac.yaml"


class Solver:
    """fk, solve and solutions of one hand as CasADi Functions."""

    def __init__(self, tree, tool=np.eye(4)):
        self.hand = hand = Hand(tree, tool)
        self.arm = hand.closed_form
        assert self.arm is not None
        q, qn, R, p = ca.SX.sym("q", 6), ca.SX.sym("qn", 6), ca.SX.sym("R", 3, 3), ca.SX.sym("p", 3)
        self.fk = ca.Function("fk", [q], list(hand.pose(q)))
        self.solve_pose = ca.Function("solve", [R, p, qn], [self.arm.solve(R, p, qn)])
        self._all = ca.Function("solutions", [R, p], [ca.horzcat(*self.arm.solutions(R, p))])
        self.lower = np.array([j.limits.lower if j.limits.lower is not None else -np.pi for j in tree.joints])
        self.upper = np.array([j.limits.upper if j.limits.upper is not None else np.pi for j in tree.joints])

    def pose(self, q):
        R, p = self.fk(q)
        return np.array(R), np.array(p).ravel()

    def solve(self, q_pose, q_near):
        return np.array(self.solve_pose(*self.pose(q_pose), q_near)).ravel()

    def solutions(self, q_pose):
        return np.array(self._all(*self.pose(q_pose))).T  # 8 x 6

    def pose_error(self, q, q_pose) -> float:
        (R, p), (R0, p0) = self.pose(q), self.pose(q_pose)
        return max(np.abs(R - R0).max(), np.abs(p - p0).max())


def wrapped(d):
    return np.angle(np.exp(1j * np.asarray(d)))


def puma_tree(path=PUMA):
    system = load_system(str(path))
    return system.nodes["arm"].leaf


def rmac_solver() -> Solver:
    system = load_system(str(RMAC))
    return Solver(system.nodes["arm"].leaf, system.root_node.hand.tool)


def variant(tmp_path, name, joints=None, **chain) -> Path:
    """specs/puma560.yaml with some DH entries (joint index -> dict) and chain keys changed."""
    data = yaml.safe_load(PUMA.read_text())
    data["name"] = name
    spec = data["nodes"]["arm"]["define"]["chain"]
    spec.update(chain)
    for i, dh in (joints or {}).items():
        spec["joints"][i]["dh"].update(dh)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def check_eight_solutions(solver: Solver, rng, samples: int, shoulder_out_of_reach: bool = False) -> float:
    """Every solution reproduces the pose, the eight are distinct and one is the generating q.
    With ``shoulder_out_of_reach`` (axes 1 and 2 apart), the elbow may not reach from the
    other shoulder's side: those four are then NaN in every angle."""
    worst = 0.0
    for _ in range(samples):
        q0 = rng.uniform(solver.lower, solver.upper)
        Q = solver.solutions(q0)
        missing = np.isnan(Q).any(axis=1)
        if missing.any():
            assert shoulder_out_of_reach and np.isnan(Q[missing]).all()
            assert list(missing) in ([False] * 4 + [True] * 4, [True] * 4 + [False] * 4)
            Q = Q[~missing]
        worst = max(worst, max(solver.pose_error(q, q0) for q in Q))
        apart = [np.abs(wrapped(Q[i] - Q[j])).max() for i in range(len(Q)) for j in range(i)]
        assert min(apart) > 1e-6, f"solutions of {q0} coincide"
        assert min(np.abs(wrapped(Q - q0)).max(axis=1)) < 1e-9, f"{q0} is not among its solutions"
        assert np.all(np.abs(Q) <= np.pi)
    return worst


@pytest.mark.parametrize("which", ["puma560", "puma560_rmac"])
def test_all_eight_solutions_reproduce_the_pose(which):
    solver = Solver(puma_tree()) if which == "puma560" else rmac_solver()
    worst = check_eight_solutions(solver, np.random.default_rng(5), 40)
    print(f"\n  {which}: 8 solutions of 40 random poses, worst pose error {worst:.1e}")
    assert worst < 1e-12


def test_a_general_member_of_the_family(tmp_path):
    """Axis 1 off the base origin, tilted 60 degrees to axes 2 and 3 and 0.1 m from axis 2;
    axis 6 perpendicular to axis 4 at q = 0; a tool turned and moved: still solved exactly
    (the shoulder's two sides now put the elbow at different distances, so some poses have
    four solutions)."""
    path = variant(
        tmp_path,
        "general_elbow",
        {0: {"a": 0.1, "alpha": "pi/3", "d": 0.3}, 4: {"theta": "pi/2"}, 5: {"d": 0.05}},
        base={"xyz": [0.2, -0.1, 0.5], "rpy": [0.3, -0.2, 0.1]},
        tool={"xyz": [0.01, 0.02, 0.1], "rpy": [0.4, 0.5, -0.6]},
    )
    solver = Solver(puma_tree(path))
    arm = solver.arm
    assert abs(abs(arm.w1 @ arm.w2) - 0.5) < 1e-12 and abs(arm.a @ arm.c) < 1e-12
    rng = np.random.default_rng(6)
    worst = check_eight_solutions(solver, rng, 20, shoulder_out_of_reach=True)
    assert worst < 1e-12
    for _ in range(10):
        q0 = rng.uniform(solver.lower, solver.upper)
        np.testing.assert_allclose(solver.solve(q0, q0 + 0.01 * rng.standard_normal(6)), q0, atol=1e-9)


def test_solve_picks_the_branch_of_q_near():
    """q_near beside any of the eight solutions returns that solution; the generating angles
    perturbed by 0.05 rad return the generating angles."""
    solver = rmac_solver()
    rng = np.random.default_rng(8)
    tried = 0
    for _ in range(30):
        q0 = rng.uniform(solver.lower, solver.upper)
        back = solver.solve(q0, q0 + 0.05 * rng.standard_normal(6))
        np.testing.assert_allclose(back, q0, atol=1e-9)
        Q = solver.solutions(q0)
        # each branch pair apart by more than the perturbation (shoulder q1, elbow q3, wrist q4)
        if (
            min(
                np.abs(wrapped(Q[i, j] - Q[k, j]))
                for j, pairs in ((0, 4), (2, 2), (3, 1))
                for i in range(8)
                for k in range(8)
                if k == i ^ pairs
            )
            < 0.2
        ):
            continue
        tried += 1
        for q in Q:
            near = q + 0.01 * rng.standard_normal(6)
            np.testing.assert_allclose(solver.solve(q0, near), q, atol=1e-9)
    assert tried >= 20


def test_angles_are_unwrapped_to_q_near():
    """q6 = 4 rad (the PUMA's q6 spans +-266 degrees) comes back as 4, not 4 - 2 pi, and every
    angle is the 2 pi multiple nearest q_near."""
    solver = rmac_solver()
    for q0 in ([0.3, 0.5, -0.4, 0.7, 0.8, 4.0], [-0.2, 1.0, -1.5, 2.5, -0.9, -4.5]):
        q0 = np.array(q0)
        np.testing.assert_allclose(solver.solve(q0, q0 + 0.02), q0, atol=1e-9)
        turns = np.array([1, -1, 2, 0, -1, 1])
        near = q0 + 2 * np.pi * turns + 0.3
        np.testing.assert_allclose(solver.solve(q0, near), q0 + 2 * np.pi * turns, atol=1e-9)


@pytest.mark.parametrize("q5", [0.0, 1e-12, 1e-9])
def test_singular_wrist_holds_q4(q5):
    """At q5 = 0 (axes 4 and 6 in line) q4 stays at q_near's and q6 takes the turn; within
    1e-8 of it the pose is met to about q5 times the held angle's error."""
    solver = rmac_solver()
    q0 = np.array([0.3, 0.5, -0.4, 0.7, q5, -1.1])
    near = q0 + np.array([0.01, -0.01, 0.01, 0.3, 0.01, -0.01])
    q = solver.solve(q0, near)
    assert q[3] == near[3]
    np.testing.assert_allclose(q[[0, 1, 2]], q0[[0, 1, 2]], atol=1e-12)
    np.testing.assert_allclose(q[5], q0[5] - 0.3, atol=1e-12 + 2 * q5)  # q4 + q6 is what the hand sees
    assert solver.pose_error(q, q0) < 1e-14 + 2 * q5


def test_out_of_reach_is_nan_and_the_edge_is_not():
    """A hand 2 m beyond its pose and a wrist centre on axis 1 are NaN in every angle; the
    elbow stretched out (the square root at its zero) is solved."""
    solver = rmac_solver()
    R, p = solver.pose(np.zeros(6))
    qn = np.zeros(6)
    far = np.array(solver.solve_pose(R, p + np.array([2.0, 0, 0]), qn)).ravel()
    on_axis_1 = np.array(solver.solve_pose(R, np.array([0, 0, 0.3]) - R @ solver.arm.wrist_in_hand, qn)).ravel()
    assert np.isnan(far).all() and np.isnan(on_axis_1).all()  # the shoulder offset keeps it 0.15 m away
    # the elbow stretched out: the wrist centre at its farthest from the shoulder
    arm = solver.arm
    psi0 = np.arctan2(arm.U[0] * arm.D[1] - arm.U[1] * arm.D[0], arm.D @ arm.U)
    stretched = np.array([0.4, 0.3, arm.sign3 * psi0, 0.2, 0.5, 0.1])
    q = solver.solve(stretched, stretched + 0.01)
    assert np.isfinite(q).all() and solver.pose_error(q, stretched) < 1e-7


def test_membership_of_the_family(tmp_path):
    """The PUMA with and without its tool is in; the Stanford arm (a prismatic joint), the UR5
    (no spherical wrist) and a PUMA whose wrist axes miss by 1e-3 m are not; a miss of 1e-12 m
    is rounding, and is solved as exact."""
    assert spherical_wrist_arm(puma_tree()) is not None
    stanford = load_system(str(ROOT / "specs" / "stanford.yaml"))
    assert spherical_wrist_arm(stanford.nodes[stanford.root].leaf) is None
    ur5 = read_urdf(str(robots_dir() / UR5[0]), UR5[1]).tree
    assert ur5.nq == 6 and spherical_wrist_arm(ur5) is None
    assert Hand(ur5, np.eye(4)).closed_form is None  # Newton steps as before
    assert spherical_wrist_arm(puma_tree(variant(tmp_path, "missed", {4: {"d": 1e-3}}))) is None
    assert spherical_wrist_arm(puma_tree(variant(tmp_path, "parallel_1", {0: {"alpha": 0}}))) is None
    solver = Solver(puma_tree(variant(tmp_path, "rounded", {4: {"d": 1e-12}})))
    q0 = np.array([0.3, 0.5, -0.4, 0.7, 0.8, -1.1])
    assert solver.pose_error(solver.solve(q0, q0), q0) < 1e-11


def test_stage_1_costs_tens_of_operations():
    """Table 1's stage 1 (Lee and Lee 1983: 39 multiplications, 32 additions) in closed form,
    against the Newton solve's hundreds."""
    rows = stage_counts(load_system(str(RMAC)))["rows"]
    counts = next(r["robotgen"] for r in rows if r["name"] == "inverse kinematics")
    print(f"\n  stage 1 of puma560_rmac: {counts}")
    assert counts["mul"] < 100 and counts["add"] < 100 and counts["total"] < 250
    hand = rmac_solver().hand
    R, p, q = ca.SX.sym("R", 3, 3), ca.SX.sym("p", 3), ca.SX.sym("q", 6)
    hand.closed_form = None
    newton = count_operations([R, p, q], [hand.inverse_kinematics(R, p, q, 2)])
    assert newton["total"] > 4 * counts["total"]


def test_adaptive_controller_resolves_by_the_closed_form(build_module):
    """The compiled controller's first period puts q_d at the measured q for a hand at fk(q),
    beyond pi on q6 included; a desired pose out of reach is status 2 (FloatingPointError)."""
    module = build_module(RMAC)
    solver = rmac_solver()
    system = load_system(str(RMAC))
    o, n, _ = StateLayout.of(system.root_node.hand).offsets["q_d"]
    zeros = np.zeros(6)
    for q in ([0.1, 0.6, -0.4, 0.3, 0.5, 0.2], [-0.5, 1.2, -2.0, 1.0, -0.7, 4.2]):
        q = np.array(q)
        R, p = solver.pose(q)
        pose = np.block([[R, p[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]])
        state = np.asarray(module.adaptive_init(q, zeros, pose, zeros, zeros)).ravel()
        np.testing.assert_allclose(state[o : o + n], q, atol=1e-10)
    pose[0, 3] += 2.0
    with pytest.raises(FloatingPointError):
        module.adaptive_init(q, zeros, pose, zeros, zeros)
