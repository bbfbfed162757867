"""Resolved motion rate control (Whitney 1972): the `resolved_rate` control law over a chain.

The PUMA 560 of specs/puma560_rmrc.yaml and a UR5 (example-robot-data, through a `urdf`
leaf) are compiled and their generated steps integrated; the other variants (Panda, planar
arm, tool and spherical frames) evaluate the CasADi graphs the C is printed from
(robotgen.symbolic.kernels_for), which keeps the suite fast. Every test prints its numbers.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from robots import PANDA, UR5, robots_dir
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from robotgen.cli import main
from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.symbolic import kernels_for

ROOT = Path(__file__).resolve().parents[2]
PUMA_RMRC = ROOT / "specs" / "puma560_rmrc.yaml"
QN = np.array([0, np.pi / 4, np.pi, 0, np.pi / 4, 0])  # the PUMA's nominal pose


def rk4(f, q, dt, steps, each=None):
    """Integrates qdot = f(q) (joint rates from a step) by classical RK4."""
    for k in range(steps):
        k1 = f(q)
        k2 = f(q + dt / 2 * k1)
        k3 = f(q + dt / 2 * k2)
        k4 = f(q + dt * k3)
        q = q + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if each is not None:
            each(k, q)
    return q


def angle(R: np.ndarray) -> float:
    return float(np.linalg.norm(Rotation.from_matrix(R).as_rotvec()))


class Graphs:
    """The kernels of a spec as CasADi functions returning numpy arrays in the module's shapes."""

    def __init__(self, spec: Path):
        self.kernels = {k.name: k for k in kernels_for(load_system(str(spec)))}

    def __getattr__(self, name):
        kernel = self.kernels[name]

        def call(*args):
            out = kernel.function(*[np.asarray(a, float).reshape(-1) for a in args])
            out = out if isinstance(out, (list, tuple)) else [out]
            shaped = [
                np.asarray(o).reshape(p.rows, p.cols) if p.is_matrix else np.asarray(o).reshape(-1)
                for o, p in zip(out, kernel.outputs)
            ]
            return shaped[0] if len(shaped) == 1 else tuple(shaped)

        return call


def write_spec(tmp_path: Path, name: str, leaf: str, settings: str) -> Path:
    spec = tmp_path / f"{name}.yaml"
    spec.write_text(
        f"robotgen: 1\nname: {name}\nroot: ctl\nnodes:\n  ctl:\n    control:\n      robot: arm\n"
        f"      law: resolved_rate\n      resolved_rate:\n{settings}\n  arm:\n    define:\n{leaf}\n"
    )
    return spec


def urdf_leaf(tmp_path: Path, robot: tuple[str, str], file: str) -> str:
    shutil.copy(robots_dir() / robot[0], tmp_path / file)
    return f"      urdf: {{file: {file}, tip: {robot[1]}}}"


PLANAR_3R = """      chain:
        convention: joints
        joints:
          - {name: a, type: revolute, axis: [0, 0, 1], limits: {lower: -2.5, upper: 2.5}}
          - {name: b, type: revolute, axis: [0, 0, 1], origin: {xyz: [0.5, 0, 0]}, limits: {lower: -2.5, upper: 2.5}}
          - {name: c, type: revolute, axis: [0, 0, 1], origin: {xyz: [0.4, 0, 0]}, limits: {lower: -0.5, upper: 0.5}}
        tool: {xyz: [0.3, 0, 0]}"""


@pytest.fixture(scope="module")
def puma(build_module):
    return build_module(PUMA_RMRC)


@pytest.fixture(scope="module")
def ur5(build_module, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ur5_rmrc")
    settings = """        frame: line_of_sight
        eye: [0.9, -0.9, 0.7]
        damping: {lambda_max: 0.05, threshold: 0.001}
        lqr: {nominal: [0, -1.2, 1.5, -1.9, -1.57, 0], q: [100, 1], r: 1}"""
    return build_module(write_spec(tmp, "ur5_rmrc", urdf_leaf(tmp, UR5, "ur5.urdf"), settings))


# -- hand-frame rate control ------------------------------------------------------------
def test_puma_reach_moves_along_the_initial_reach_axis(puma):
    """Whitney's reach (hand y) with the other five rates zero, 2 s at 1 kHz with RK4."""
    command = np.array([0, 0.05, 0, 0, 0, 0])  # sweep reach lift tilt twist turn
    T0 = puma.fk(QN)
    w_min = [np.inf]

    def track(k, q):
        w_min[0] = min(w_min[0], float(puma.rate_step(q, command)[1][0]))

    q = rk4(lambda q: puma.rate_step(q, command)[0], QN.copy(), 1e-3, 2000, track)
    T = puma.fk(q)
    d = T[:3, 3] - T0[:3, 3]
    reach = T0[:3, 1]
    lateral = np.linalg.norm(d - (d @ reach) * reach)
    drift = angle(T0[:3, :3].T @ T[:3, :3])
    print(
        f"\nPUMA reach 2 s: along {d @ reach:.9f} m, lateral {lateral:.2e} m, orientation {drift:.2e} rad, "
        f"min manipulability {w_min[0]:.4f}"
    )
    assert abs(d @ reach - 0.1) < 1e-9
    assert lateral < 1e-6 and drift < 1e-6


def test_rate_step_is_eq_4_with_the_hand_jacobian(puma):
    """Away from singularities, J_hand qd = Sdot exactly (a factorised solve, eq 4), and the
    reported manipulability and condition number are those of J_hand's singular values."""
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(50):
        q = QN + rng.uniform(-0.5, 0.5, 6)
        S = rng.uniform(-0.05, 0.05, 6)
        qd, w, cond = puma.rate_step(q, S)
        J = puma.jacobian_hand(q)
        sv = np.linalg.svd(J, compute_uv=False)
        worst = max(worst, np.abs(J @ qd - S).max())
        np.testing.assert_allclose(w[0], np.prod(sv), rtol=1e-9)
        np.testing.assert_allclose(cond[0], sv[0] / sv[-1], rtol=1e-7)
        np.testing.assert_allclose(puma.command_jacobian(q), J, atol=1e-12)
    print(f"\nmax |J qd - S| over 50 poses: {worst:.2e}")
    assert worst < 1e-12


# -- position control through rates (eqs 11-18) -----------------------------------------
def test_position_control_reaches_targets_from_random_starts(puma):
    rng = np.random.default_rng(7)
    lower = np.array([-160, -45, -225, -110, -100, -266]) * np.pi / 180
    upper = np.array([160, 225, 45, 170, 100, 266]) * np.pi / 180
    targets, starts = [], []
    while len(targets) < 20:  # reachable targets away from singularities, random starts
        qt = rng.uniform(lower, upper)
        if puma.rate_step(qt, np.zeros(6))[1][0] > 0.01:
            targets.append(qt)
            starts.append(rng.uniform(lower, upper))
    # near-pi rotations: the same position, the hand turned by pi - 1e-3 and by pi about its z
    for qt in targets[:2]:
        for turn in (np.pi - 1e-3, np.pi):
            q0 = qt.copy()
            q0[5] += turn
            targets.append(qt)
            starts.append(q0)
    goal = puma.fk(np.array(targets))
    angles0 = [angle(a[:3, :3].T @ b[:3, :3]) for a, b in zip(puma.fk(np.array(starts)), goal)]
    q = rk4(lambda q: puma.position_step(q, goal)[0], np.array(starts), 5e-3, 2000)  # 10 s
    error = puma.position_step(q, goal)[1]
    pos, rot = np.linalg.norm(error[:, :3], axis=1), np.linalg.norm(error[:, 3:], axis=1)
    fk = puma.fk(q)
    direct = [angle(a[:3, :3].T @ b[:3, :3]) for a, b in zip(fk, goal)]
    print(
        f"\n{len(starts)} starts (initial rotations up to {max(angles0):.6f} rad): final position error "
        f"max {pos.max():.2e} m, rotation {rot.max():.2e} rad (directly {max(direct):.2e})"
    )
    assert pos.max() < 1e-6 and rot.max() < 1e-6 and max(direct) < 1e-6
    assert np.abs(fk[:, :3, 3] - goal[:, :3, 3]).max() < 1e-6


def test_axis_angle_of_eqs_15_to_18_handles_every_angle():
    """The rotation vector of C_if (eqs 14-18) against scipy, with Omega along the hand x axis
    (eq 18's special case), tiny angles, and angles at and next to pi."""
    from robotgen.symbolic.rigid_body.axis_angle import rotation_vector

    C = ca.SX.sym("C", 3, 3)
    f = ca.Function("rv", [C], [rotation_vector(C)])
    rng = np.random.default_rng(0)
    axes = [np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])]
    axes += [a / np.linalg.norm(a) for a in rng.normal(size=(20, 3))]
    worst = 0.0
    for a in axes:
        for alpha in (0.0, 1e-12, 1e-6, 0.3, 1.5, 2.5, np.pi - 1e-6, np.pi - 1e-9):
            R = Rotation.from_rotvec(alpha * a).as_matrix()
            got = np.array(f(R)).ravel()
            worst = max(worst, np.abs(got - alpha * a).max())
        R = Rotation.from_rotvec(np.pi * a).as_matrix()  # at pi either sign is right
        got = np.array(f(R)).ravel()
        worst = max(worst, min(np.abs(got - np.pi * a).max(), np.abs(got + np.pi * a).max()))
    print(f"\nrotation vector error, worst over {len(axes)} axes x 9 angles: {worst:.2e} rad")
    assert worst < 1e-7  # at pi - 1e-9 the axis is defined only to ~1e-8 by rounding


# -- singularities --------------------------------------------------------------------
@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_a_nan_or_infinite_measurement_is_status_1(puma, ur5, bad):
    q = np.array([0.2, 0.6, 2.9, 0.0, 0.3, 0.0])
    broken = np.where(np.arange(6) == 3, bad, q)
    for call in (
        lambda: puma.rate_step(broken, np.ones(6)),
        lambda: puma.rate_step(q, np.where(q > 1, bad, 0)),
        lambda: puma.position_step(broken, puma.fk(q)),
        lambda: ur5.lqr_step(broken, np.zeros(6)),
    ):
        with pytest.raises(FloatingPointError, match="status 1"):
            call()
    qd, w, cond = puma.rate_step(q, np.ones(6))
    assert np.all(np.isfinite(qd)) and w[0] > 0 and cond[0] >= 1


def test_through_a_wrist_singularity_rates_stay_bounded(puma):
    """Rotating the hand about joint 5's axis takes q5 from 0.3 through 0 (a wrist singularity,
    where damping is active) to -0.3; then a command with a component about the lost axis
    z5 x z4 drives q4 and q6 to their rate limits: the rate vector is scaled, no NaN, and the
    hand keeps its commanded direction."""
    limits = np.array([2.0, 2.0, 2.0, 4.0, 4.0, 4.0])  # the spec's rate_limits
    results = {}
    for label, lost in (("through", 0.0), ("lost axis", 0.05)):
        q0 = np.array([0.2, 0.6, 2.9, 0.0, 0.3, 0.0])
        J = puma.jacobian(q0)
        z4, z5 = J[3:, 3], J[3:, 4]
        n = np.cross(z5, z4) / np.linalg.norm(np.cross(z5, z4))
        omega = -0.3 * z5 + lost * n  # base frame, fixed
        T0 = puma.fk(q0)
        stats = {"ratio": 0.0, "rot": 0.0, "pos": 0.0, "w": np.inf, "q5": []}

        def step(q):
            R = puma.fk(q)[:3, :3]
            return puma.rate_step(q, np.r_[0, 0, 0, R.T @ omega])

        def track(k, q):
            qd, w, _ = step(q)
            assert np.all(np.isfinite(qd)) and np.all(np.isfinite(q))
            T = puma.fk(q)
            ideal = Rotation.from_rotvec(omega * (k + 1) * 1e-3).as_matrix() @ T0[:3, :3]
            stats["ratio"] = max(stats["ratio"], np.max(np.abs(qd) / limits))
            stats["rot"] = max(stats["rot"], angle(ideal.T @ T[:3, :3]))
            stats["pos"] = max(stats["pos"], np.linalg.norm(T[:3, 3] - T0[:3, 3]))
            stats["w"] = min(stats["w"], float(w[0]))
            stats["q5"].append(q[4])

        rk4(lambda q: step(q)[0], q0, 1e-3, 2000, track)
        results[label] = stats
        print(
            f"\n{label}: max |qd_i|/limit_i {stats['ratio']:.6f}, min manipulability {stats['w']:.2e}, "
            f"hand position error {stats['pos']:.2e} m, orientation error {stats['rot']:.2e} rad, "
            f"q5 {min(stats['q5']):+.3f}..{max(stats['q5']):+.3f}"
        )
    through, lost = results["through"], results["lost axis"]
    assert min(through["q5"]) < -0.29 and through["w"] < 1e-4  # it did pass the singularity
    assert through["ratio"] <= 1 + 1e-12 and through["pos"] < 1e-3 and through["rot"] < 1e-3
    assert abs(lost["ratio"] - 1) < 1e-12  # limited: the whole vector is scaled
    assert lost["pos"] < 1e-9  # the hand's direction is kept: the wrist centre does not move
    assert lost["rot"] < 0.05  # it only lags while limited


# -- other command coordinates ---------------------------------------------------------
def test_line_of_sight_reach_moves_along_the_eye_hand_line(ur5):
    eye = np.array([0.9, -0.9, 0.7])
    q = np.array([0.3, -1.3, 1.6, -1.8, -1.5, 0.2])
    T0 = ur5.fk(q)
    line = (T0[:3, 3] - eye) / np.linalg.norm(T0[:3, 3] - eye)
    command = np.array([0, 0.05, 0, 0, 0, 0])  # sweep sight lift tilt twist turn
    q = rk4(lambda q: ur5.rate_step(q, command)[0], q, 1e-3, 2000)
    T = ur5.fk(q)
    d = T[:3, 3] - T0[:3, 3]
    off = np.linalg.norm(d - (d @ line) * line)
    drift = angle(T0[:3, :3].T @ T[:3, :3])
    # eq 10: the sight row is the motion along the unit eye-hand vector
    J = ur5.command_jacobian(q)
    b = (T[:3, 3] - eye) / np.linalg.norm(T[:3, 3] - eye)
    print(f"\nline of sight 2 s: along {d @ line:.9f} m, off the line {off:.2e} m, orientation {drift:.2e} rad")
    np.testing.assert_allclose(J[1], b @ ur5.jacobian(q)[:3], atol=1e-12)
    assert abs(d @ line - 0.1) < 1e-9 and off < 1e-6 and drift < 1e-6


def test_tool_axes_active_subset_and_weights(tmp_path):
    """A held tool's axes; only reach and lift follow the command (lift at twice the rate),
    the other axes are held whatever the command says."""
    settings = """        frame: tool
        tool: {xyz: [0, 0.05, 0.12], rpy: [0.3, 0, 0.5]}
        active: [reach, lift]
        weights: [1, 1, 2, 1, 1, 1]"""
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    g = Graphs(write_spec(tmp_path, "puma_tool", leaf, settings))
    tool = np.eye(4)
    tool[:3, :3] = Rotation.from_euler("xyz", [0.3, 0, 0.5]).as_matrix()
    tool[:3, 3] = [0, 0.05, 0.12]
    q0 = QN.copy()
    P0 = g.fk(q0) @ tool
    command = np.array([9.0, 0.03, 0.01, 9.0, 9.0, 9.0])  # the 9s are on held axes
    q = rk4(lambda q: g.rate_step(q, command)[0], q0, 2e-3, 500)  # 1 s
    P = g.fk(q) @ tool
    d = P0[:3, :3].T @ (P[:3, 3] - P0[:3, 3])  # in the initial tool axes
    drift = angle(P0[:3, :3].T @ P[:3, :3])
    print(f"\ntool frame 1 s: displacement in tool axes {d}, orientation {drift:.2e} rad")
    np.testing.assert_allclose(d, [0, 0.03, 0.02], atol=1e-9)
    assert drift < 1e-9


def test_spherical_coordinates_about_a_centre(tmp_path):
    centre = np.array([0.2, -0.1, 0.3])
    settings = f"""        frame: spherical
        centre: [{centre[0]}, {centre[1]}, {centre[2]}]"""
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    g = Graphs(write_spec(tmp_path, "puma_sph", leaf, settings))

    def spherical(q):
        d = g.fk(q)[:3, 3] - centre
        return np.array([np.linalg.norm(d), np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1]))])

    q0 = QN + 0.1
    J = g.command_jacobian(q0)
    h = 1e-6
    numeric = np.array([(spherical(q0 + h * e) - spherical(q0 - h * e)) / (2 * h) for e in np.eye(6)]).T
    np.testing.assert_allclose(J[:3], numeric, atol=1e-8)
    # a pure azimuth rate turns the hand about the vertical through the centre
    s0, R0 = spherical(q0), g.fk(q0)[:3, :3]
    q = rk4(lambda q: g.rate_step(q, [0, 0.2, 0, 0, 0, 0])[0], q0, 2e-3, 500)  # 1 s
    s = spherical(q)
    drift = angle(R0.T @ g.fk(q)[:3, :3])
    print(f"\nspherical: (r, azimuth, elevation) {s0} -> {s}, orientation {drift:.2e} rad")
    np.testing.assert_allclose(s - s0, [0, 0.2, 0], atol=1e-9)
    assert drift < 1e-9


# -- redundancy ---------------------------------------------------------------------------
def test_panda_null_space_objective_keeps_the_hand_command_exact(tmp_path):
    settings = """        frame: hand
        redundancy: {method: pseudo_inverse, objective: joint_limits, gain: 50}
        damping: {lambda_max: 0.05, threshold: 0.005}"""
    g = Graphs(write_spec(tmp_path, "panda_rmrc", urdf_leaf(tmp_path, PANDA, "panda.urdf"), settings))
    q0 = np.array([2.2, -1.2, 0.3, -2.4, 0.2, 2.8, 0.6])  # some joints near their limits
    command = np.array([0.0, 0.04, 0.0, 0.0, 0.0, 0.0])
    T0 = g.fk(q0)
    worst = [0.0]

    def check(k, q):
        qd = g.rate_step(q, command)[0]
        worst[0] = max(worst[0], np.abs(g.jacobian_hand(q) @ qd - command).max())

    q = rk4(lambda q: g.rate_step(q, command)[0], q0, 2e-3, 1000, check)  # 2 s
    # the same motion by the minimum-norm pseudo-inverse alone (numpy), for comparison
    plain = rk4(lambda q: np.linalg.pinv(g.jacobian_hand(q)) @ command, q0, 2e-3, 1000)
    T = g.fk(q)
    d = T[:3, 3] - T0[:3, 3]
    lateral = np.linalg.norm(d - (d @ T0[:3, 1]) * T0[:3, 1])
    drift = angle(T0[:3, :3].T @ T[:3, :3])
    H0, H, Hp = (float(g.objective(x)[0]) for x in (q0, q, plain))
    print(
        f"\nPanda 2 s reach: |J qd - S| max {worst[0]:.2e}, along {d @ T0[:3, 1]:.9f} m, lateral {lateral:.2e} m, "
        f"orientation {drift:.2e} rad; joint-limit objective {H0:.4f} -> {H:.4f} (pseudo-inverse alone {Hp:.4f})"
    )
    assert worst[0] < 1e-10 and lateral < 1e-6 and drift < 1e-6 and abs(d @ T0[:3, 1] - 0.08) < 1e-9
    assert H > H0 + 0.01 and H > Hp + 0.01


def test_panda_manipulability_gradient_in_the_null_space(tmp_path):
    settings = """        frame: base
        redundancy: {objective: manipulability, gain: 100}"""
    g = Graphs(write_spec(tmp_path, "panda_w", urdf_leaf(tmp_path, PANDA, "panda.urdf"), settings))
    q0 = np.array([0.3, -0.3, 0.5, -0.5, 0.4, 0.4, 0.8])  # elbow nearly stretched: low manipulability
    T0 = g.fk(q0)
    q = rk4(lambda q: g.rate_step(q, np.zeros(6))[0], q0, 5e-3, 400)  # 2 s of self-motion
    T = g.fk(q)
    w0, w = g.rate_step(q0, np.zeros(6))[1][0], g.rate_step(q, np.zeros(6))[1][0]
    moved = np.linalg.norm(T[:3, 3] - T0[:3, 3])
    print(
        f"\nPanda self-motion: manipulability {w0:.5f} -> {w:.5f}, hand moved {moved:.2e} m, "
        f"turned {angle(T0[:3, :3].T @ T[:3, :3]):.2e} rad, joints moved {np.linalg.norm(q - q0):.3f} rad"
    )
    np.testing.assert_allclose(g.objective(q)[0], w, rtol=1e-9)
    assert w > 1.5 * w0 and moved < 1e-8 and angle(T0[:3, :3].T @ T[:3, :3]) < 1e-8


def test_extended_jacobian_planar_arm(tmp_path):
    """Baillieul's extended Jacobian on a planar 3R arm with a 2-D task (x, y): the hand
    follows the command exactly and the optimality condition z^T grad H decays to zero."""
    settings = """        frame: base
        free: [z, rx, ry, rz]
        redundancy: {method: extended_jacobian, objective: joint_limits, gain: 5.0}"""
    g = Graphs(write_spec(tmp_path, "planar_ext", PLANAR_3R, settings))
    q0 = np.array([0.3, 0.9, 0.45])
    command = np.array([-0.05, 0.02, 0, 0, 0, 0])

    def condition(q):
        J = g.jacobian(q)[:2]
        z = np.linalg.svd(J)[2][-1]
        grad = np.array([-(q[0]) / 2.5**2, -(q[1]) / 2.5**2, -(q[2]) / 0.5**2]) / 3
        return z @ grad

    p0 = g.fk(q0)[:2, 3]
    q = rk4(lambda q: g.rate_step(q, command)[0], q0, 2e-3, 1000)  # 2 s
    p = g.fk(q)[:2, 3]
    print(
        f"\nextended Jacobian: hand moved {p - p0} (commanded {2 * command[:2]}), z^T grad H "
        f"{condition(q0):.3e} -> {condition(q):.3e}, joints {q0} -> {q}"
    )
    np.testing.assert_allclose(p - p0, 2 * command[:2], atol=1e-9)
    assert abs(condition(q)) < 1e-4 * abs(condition(q0))


# -- the regulator on the linearised dynamics (eq 19) ------------------------------------------
def test_lqr_closes_the_loop_on_the_linear_and_the_nonlinear_model(ur5):
    lqr = ur5.lqr
    A, B, K = (np.array(lqr[k]) for k in ("A", "B", "K"))
    q0 = np.array(lqr["nominal"])
    n = len(q0)
    # eq 19 from the symbolic model: against central differences of the compiled dynamics
    tau0 = ur5.gravity(q0)
    h = 1e-6
    fd_A = np.zeros((2 * n, 2 * n))
    fd_B = np.zeros((2 * n, n))
    for i in range(n):
        e = np.eye(n)[i] * h
        fd_A[n:, i] = (
            ur5.forward_dynamics(q0 + e, np.zeros(n), tau0) - ur5.forward_dynamics(q0 - e, np.zeros(n), tau0)
        ) / (2 * h)
        fd_A[n:, n + i] = (ur5.forward_dynamics(q0, e, tau0) - ur5.forward_dynamics(q0, -e, tau0)) / (2 * h)
        fd_B[n:, i] = (
            ur5.forward_dynamics(q0, np.zeros(n), tau0 + e) - ur5.forward_dynamics(q0, np.zeros(n), tau0 - e)
        ) / (2 * h)
    fd_A[:n, n:] = np.eye(n)
    np.testing.assert_allclose(A, fd_A, atol=1e-5 * np.abs(A).max())
    np.testing.assert_allclose(B, fd_B, atol=1e-5 * np.abs(B).max())
    np.testing.assert_allclose(np.array(lqr["tau0"]), tau0, atol=1e-9)
    report = ur5.info()["rate_control"]["lqr"]
    assert report["controllable"] and report["observable_from_positions"] and report["stable"]
    assert report["controllability_rank"] == report["observability_rank_from_positions"] == 2 * n

    s0 = np.r_[np.full(n, 0.05), np.zeros(n)]
    t_end, dt = 10.0, 1e-3
    closed = A - B @ K
    # the full nonlinear model, torques from the generated lqr_step, RK4 at 1 kHz
    x = np.r_[q0, np.zeros(n)] + s0
    gap = peak = 0.0

    def f(x):
        q, qd = x[:n], x[n:]
        return np.r_[qd, ur5.forward_dynamics(q, qd, ur5.lqr_step(q, qd))]

    for k in range(int(round(t_end / dt))):
        k1 = f(x)
        k2 = f(x + dt / 2 * k1)
        k3 = f(x + dt / 2 * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if (k + 1) % 50 == 0:
            predicted = expm(closed * (k + 1) * dt) @ s0
            gap = max(gap, np.abs(x - np.r_[q0, np.zeros(n)] - predicted).max())
            peak = max(peak, np.abs(predicted).max())
    linear = expm(closed * t_end) @ s0
    nonlinear = x - np.r_[q0, np.zeros(n)]
    poles = np.linalg.eigvals(closed)
    print(
        f"\nLQR about {q0}: closed-loop poles max real {poles.real.max():.3f} (open loop "
        f"{report['open_loop_max_real_part']:.3f}); |s| {np.abs(s0).max():.3f} -> after {t_end:g} s linear "
        f"{np.abs(linear).max():.2e}, nonlinear {np.abs(nonlinear).max():.2e}; nonlinear - linear at most "
        f"{gap:.2e} (peak of the linear response {peak:.2e})"
    )
    assert np.abs(linear).max() < 1e-6 and np.abs(nonlinear).max() < 1e-6
    assert gap < 0.1 * peak


# -- the spec layer -----------------------------------------------------------------------
def test_module_functions_and_info(puma):
    info = puma.info()
    for name in (
        "fk",
        "jacobian",
        "jacobian_hand",
        "mass",
        "forward_dynamics",
        "command_jacobian",
        "rate_step",
        "position_step",
        "lqr_step",
    ):
        assert name in info["functions"], name
    assert "servo_step" not in info["functions"]  # only with lqr: {servo: true}
    rc = info["rate_control"]
    assert rc["frame"] == "hand" and rc["axes"] == ["sweep", "reach", "lift", "tilt", "twist", "turn"]
    assert info["nodes"]["rmrc"]["kind"] == "resolved_rate" and info["leaves"] == ["arm"]


@pytest.mark.parametrize(
    "settings, message",
    [
        ("frame: line_of_sight", "frame line_of_sight needs 'eye'"),
        ("frame: hand\n        eye: [0, 0, 1]", "'eye' belongs to frame line_of_sight, not hand"),
        ("active: [reach, wobble]", "'wobble' is not a command axis of frame hand"),
        ("active: [reach]\n        free: [reach]", "axis 'reach' is both active and free"),
        (
            "redundancy: {method: extended_jacobian, objective: joint_limits}",
            "extended_jacobian needs exactly one degree of redundancy",
        ),
        ("rate_limits: [1, 2]", "expected 6 entries (one per joint), got 2"),
        ("lqr: {nominal: [0, 0]}", "expected 6 joint positions, got 2"),
    ],
)
def test_located_errors(tmp_path, settings, message):
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    spec = write_spec(tmp_path, "bad", leaf, "        " + settings)
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    print(f"\n{text}")
    assert message in text and f"{spec}:" in text


def test_resolved_rate_must_be_the_root_over_a_chain(tmp_path):
    spec = tmp_path / "tree.yaml"
    spec.write_text("""robotgen: 1
name: bad_tree
root: ctl
nodes:
  ctl:
    control: {robot: arm, law: resolved_rate, kp: 1}
  arm:
    define:
      formulas: {coordinates: [x], M: [["1"]]}
""")
    assert main(["check", str(spec)]) == 1
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    assert "takes no kp" in text and "controls a chain or urdf leaf" in text
