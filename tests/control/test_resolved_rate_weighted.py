"""The weighted pseudo-inverse of law resolved_rate on a redundant arm:
`redundancy: {method: weighted_pseudo_inverse, joint_weights: [...]}`, qdot = W^-1 J^T
(J W^-1 J^T)^-1 Sdot, the joint rate of least qdot^T W qdot that meets the hand rates.

A Panda (example-robot-data, through a `urdf` leaf; 7 joints) with its hand position as the
task (3 rows, a 4-dimensional null space) or its whole twist (6 rows). The CasADi graphs the
C is printed from are evaluated (robotgen.symbolic.kernels_for) against numpy's closed forms.
Every test prints its numbers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from robots import PANDA
from test_resolved_rate_chain import Graphs, urdf_leaf, write_spec

from robotgen.errors import UserErrors
from robotgen.frontend import load_system

PUMA_RMRC = Path(__file__).resolve().parents[2] / "specs" / "puma560_rmrc.yaml"

WEIGHTS = np.array([100.0, 2.0, 1.0, 0.5, 1.0, 3.0, 1.0])  # joint 1 heavily weighted
Q0 = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7])
TASKS = {"position": "        frame: base\n        free: [rx, ry, rz]", "twist": "        frame: base"}


def panda(tmp_path, name: str, task: str, redundancy: str = "", extra: str = "") -> Graphs:
    settings = task + (f"\n        redundancy: {redundancy}" if redundancy else "") + extra
    return Graphs(write_spec(tmp_path, name, urdf_leaf(tmp_path, PANDA, f"{name}.urdf"), settings))


def weighted(weights) -> str:
    return f"{{method: weighted_pseudo_inverse, joint_weights: {list(map(float, weights))}}}"


def samples(rows: int, count: int = 20, seed: int = 4):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield Q0 + rng.uniform(-0.4, 0.4, 7), rng.uniform(-0.1, 0.1, rows)


def task_jacobian(g: Graphs, q: np.ndarray, rows: int) -> np.ndarray:
    return g.command_jacobian(q)[:rows]


def null_basis(J: np.ndarray) -> np.ndarray:
    """Orthonormal columns spanning null(J), from the SVD."""
    return np.linalg.svd(J)[2][J.shape[0] :].T


@pytest.mark.parametrize("task, rows", [("position", 3), ("twist", 6)])
def test_weighted_rates_are_the_closed_form_and_the_least_weighted_norm(tmp_path, task, rows):
    """For 20 poses and hand rates: J qdot = Sdot, qdot = W^-1 J^T (J W^-1 J^T)^-1 Sdot
    (numpy), qdot^T W z = 0 for every z in null(J) (the optimality condition: W qdot lies in
    range(J^T)), so every null-space perturbation raises qdot^T W qdot by exactly
    delta^T W delta > 0 (to rounding of the cost)."""
    g = panda(tmp_path, f"panda_w_{task}", TASKS[task], weighted(WEIGHTS))
    W, Wi = np.diag(WEIGHTS), np.diag(1 / WEIGHTS)
    rng = np.random.default_rng(8)
    worst = {"task": 0.0, "closed": 0.0, "gradient": 0.0, "rise": 0.0}
    for q, S in samples(rows):
        qd = g.rate_step(q, np.r_[S, np.zeros(6 - rows)])[0]
        J = task_jacobian(g, q, rows)
        closed = Wi @ J.T @ np.linalg.solve(J @ Wi @ J.T, S)
        Z = null_basis(J)
        cost = qd @ W @ qd
        worst["task"] = max(worst["task"], np.abs(J @ qd - S).max())
        worst["closed"] = max(worst["closed"], np.abs(qd - closed).max() / np.abs(closed).max())
        worst["gradient"] = max(
            worst["gradient"], np.abs(Z.T @ W @ qd).max() / (np.linalg.norm(W) * np.linalg.norm(qd))
        )
        for _ in range(20):
            delta = Z @ rng.normal(size=Z.shape[1]) * 0.01 * np.linalg.norm(qd)
            rise = (qd + delta) @ W @ (qd + delta) - cost
            assert rise > 0
            worst["rise"] = max(worst["rise"], abs(rise - delta @ W @ delta) / cost)
    print(
        f"\n{task} task ({rows} rows), W = diag({WEIGHTS.tolist()}), 20 poses: |J qd - S| {worst['task']:.1e}, "
        f"|qd - closed form| / |qd| {worst['closed']:.1e}, |Z^T W qd| / (|W| |qd|) {worst['gradient']:.1e}, "
        f"null-space perturbations: |rise - delta^T W delta| / cost up to {worst['rise']:.1e}"
    )
    assert worst["task"] < 1e-12 and worst["closed"] < 1e-12 and worst["gradient"] < 1e-13 and worst["rise"] < 1e-14


def test_a_heavily_weighted_joint_moves_less(tmp_path):
    """Joint 1 weighted 100, the others 1, against unit weights (the plain pseudo-inverse,
    itself checked against numpy's pinv). Raising one weight w_i never lets that joint move
    more: the optima x, x' for w < w' satisfy w x_i^2 + f(x) <= w x'_i^2 + f(x') and
    w' x'_i^2 + f(x') <= w' x_i^2 + f(x), whose sum is (w' - w)(x'_i^2 - x_i^2) <= 0. So at
    every pose |qd_1| is at most its unit-weight value (typically far smaller), and the first
    inequality then gives f(x) <= f(x'): the other joints move at least as much."""
    heavy = panda(tmp_path, "panda_heavy", TASKS["position"], weighted([100, 1, 1, 1, 1, 1, 1]))
    plain = panda(tmp_path, "panda_plain1", TASKS["position"])
    ratios, others = [], []
    for q, S in samples(3):
        command = np.r_[S, 0, 0, 0]
        qd, unit = heavy.rate_step(q, command)[0], plain.rate_step(q, command)[0]
        np.testing.assert_allclose(unit, np.linalg.pinv(task_jacobian(plain, q, 3)) @ S, atol=1e-12)
        assert abs(qd[0]) <= abs(unit[0]) * (1 + 1e-12)
        ratios.append(abs(qd[0]) / abs(unit[0]))
        others.append(np.linalg.norm(qd[1:]) / np.linalg.norm(unit[1:]))
    print(
        f"\n20 poses, joint 1 weighted 100: |qd_1| / |qd_1 (unit weights)| {min(ratios):.4f}..{max(ratios):.4f} "
        f"(median {np.median(ratios):.4f}); the other joints' |qd| / unit {min(others):.3f}..{max(others):.3f}"
    )
    assert np.median(ratios) < 0.1 and min(others) >= 1 - 1e-12  # the others make up for it


def test_unit_and_uniform_weights_are_the_plain_pseudo_inverse(tmp_path):
    """W = I is the plain pseudo-inverse bit for bit; W = 3 I (any c I) gives the same rates,
    W^-1 J^T (J W^-1 J^T)^-1 = J^T (J J^T)^-1, to rounding."""
    task = TASKS["position"]
    plain = panda(tmp_path, "panda_plain", task, "{method: pseudo_inverse}")
    unit = panda(tmp_path, "panda_unit", task, weighted(np.ones(7)))
    uniform = panda(tmp_path, "panda_uniform", task, "{method: weighted_pseudo_inverse, joint_weights: 3}")
    worst = 0.0
    for q, S in samples(3):
        command = np.r_[S, 0, 0, 0]
        a, b, c = plain.rate_step(q, command)[0], unit.rate_step(q, command)[0], uniform.rate_step(q, command)[0]
        assert np.array_equal(a, b)
        worst = max(worst, np.abs(c - a).max() / np.abs(a).max())
    print(f"\n20 poses: W = I equals the plain pseudo-inverse bit for bit; W = 3 I differs by {worst:.1e} (relative)")
    assert worst < 4e-15  # a few roundings: 1/sqrt(3) is not exact


def test_damped_weighted_rates(tmp_path):
    """With damping on (threshold above every manipulability met): qdot = W^-1 J^T
    (J W^-1 J^T + lambda^2 I)^-1 Sdot, lambda^2 = lambda_max^2 (1 - w / threshold)^2, w the
    manipulability sqrt(det(J J^T)) of the unweighted task Jacobian."""
    lam, threshold = 0.05, 10.0
    g = panda(
        tmp_path,
        "panda_wd",
        TASKS["position"],
        weighted(WEIGHTS),
        f"\n        damping: {{lambda_max: {lam}, threshold: {threshold}}}",
    )
    Wi = np.diag(1 / WEIGHTS)
    worst, smallest = 0.0, np.inf
    for q, S in samples(3):
        qd, w, _ = g.rate_step(q, np.r_[S, 0, 0, 0])
        J = task_jacobian(g, q, 3)
        np.testing.assert_allclose(w[0], np.sqrt(np.linalg.det(J @ J.T)), rtol=1e-10)
        lam2 = lam**2 * (1 - w[0] / threshold) ** 2
        closed = Wi @ J.T @ np.linalg.solve(J @ Wi @ J.T + lam2 * np.eye(3), S)
        worst = max(worst, np.abs(qd - closed).max() / np.abs(closed).max())
        smallest = min(smallest, np.abs(J @ qd - S).max())
    print(f"\ndamped, 20 poses: |qd - closed form| / |qd| {worst:.1e}; the damping leaves |J qd - S| >= {smallest:.1e}")
    assert worst < 1e-12 and smallest > 1e-6  # damping acted


def test_null_space_objective_is_projected_in_the_weighted_metric(tmp_path):
    """With objective joint_limits (gain k): qdot = J#W Sdot + (I - J#W J) W^-1 k grad H,
    J#W = W^-1 J^T (J W^-1 J^T)^-1; grad H by central differences of the module's
    objective(q). Its null-space part n is the W-orthogonal projection of W^-1 k grad H onto
    null(J): J n = 0 and Z^T W (W^-1 k grad H - n) = 0; it raises H (grad H . n >= 0)."""
    gain = 2.0
    g = panda(
        tmp_path,
        "panda_wh",
        TASKS["position"],
        f"{{method: weighted_pseudo_inverse, joint_weights: {WEIGHTS.tolist()}, objective: joint_limits, "
        f"gain: {gain}}}",
    )
    W, Wi = np.diag(WEIGHTS), np.diag(1 / WEIGHTS)
    worst = {"closed": 0.0, "task": 0.0, "orthogonal": 0.0}
    for q, S in samples(3):
        qd = g.rate_step(q, np.r_[S, 0, 0, 0])[0]
        J = task_jacobian(g, q, 3)
        h = 1e-6
        grad = np.array([(g.objective(q + h * e)[0] - g.objective(q - h * e)[0]) / (2 * h) for e in np.eye(7)])
        J_w = Wi @ J.T @ np.linalg.inv(J @ Wi @ J.T)
        closed = J_w @ S + (np.eye(7) - J_w @ J) @ Wi @ (gain * grad)
        n = qd - J_w @ S
        Z = null_basis(J)
        worst["closed"] = max(worst["closed"], np.abs(qd - closed).max() / np.abs(closed).max())
        worst["task"] = max(worst["task"], np.abs(J @ qd - S).max())
        worst["orthogonal"] = max(
            worst["orthogonal"], np.abs(Z.T @ (gain * grad - W @ n)).max() / np.abs(gain * grad).max()
        )
        assert grad @ n >= 0
    print(
        f"\nweighted + joint_limits, 20 poses: |qd - closed form| / |qd| {worst['closed']:.1e} (grad H by central "
        f"differences), |J qd - S| {worst['task']:.1e}, |Z^T W (W^-1 k grad H - n)| / |k grad H| "
        f"{worst['orthogonal']:.1e}"
    )
    assert worst["closed"] < 1e-8 and worst["task"] < 1e-12 and worst["orthogonal"] < 1e-8


# -- the spec layer ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "settings, message",
    [
        (
            "redundancy: {method: weighted_pseudo_inverse, joint_weights: [1, 2]}",
            "expected 6 entries (one per joint), got 2",
        ),
        (
            "redundancy: {method: weighted_pseudo_inverse, joint_weights: [1, 1, 0, 1, 1, 1]}",
            "joint_weights[2]: joint weight 0 must be positive",
        ),
        ("redundancy: {method: weighted_pseudo_inverse, joint_weights: -2}", "joint weight -2 must be positive"),
        ("redundancy: {method: weighted_pseudo_inverse}", "method weighted_pseudo_inverse needs joint_weights"),
        (
            "redundancy: {method: pseudo_inverse, joint_weights: 2}",
            "joint_weights belong to method weighted_pseudo_inverse, not pseudo_inverse",
        ),
        (
            "redundancy: {joint_weights: [1, 1, 1, 1, 1, 1]}",
            "joint_weights belong to method weighted_pseudo_inverse, not pseudo_inverse",
        ),
    ],
)
def test_located_errors(tmp_path, settings, message):
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    spec = write_spec(tmp_path, "bad", leaf, "        " + settings)
    line = spec.read_text().splitlines().index("        " + settings) + 1
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    print(f"\n{text}")
    assert message in text and f"{spec}:{line}:" in text


def test_weights_on_a_square_task_are_a_located_warning(tmp_path):
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    settings = "        redundancy: {method: weighted_pseudo_inverse, joint_weights: 3}"
    spec = write_spec(tmp_path, "square", leaf, settings)
    line = spec.read_text().splitlines().index(settings) + 1
    system = load_system(str(spec))
    print(f"\n{system.warnings}")
    assert len(system.warnings) == 1 and system.warnings[0].startswith(f"{spec}:{line}:")
    assert "no redundancy (6 joints, 6 task axes); the weighted pseudo-inverse is J^-1" in system.warnings[0]
    assert system.root_node.rate.summary()["redundancy"]["joint_weights"] == [3.0] * 6
