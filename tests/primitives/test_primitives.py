"""The claims of Deno, Murray, Pister & Sastry, "Control Primitives for Robot Systems" (1990),
ch. 2-5 and Appendix A, checked on the compiled Styx modules against references built here.

The references never call robotgen: the spec YAML is read with PyYAML and `reference.const`,
the contact geometry, the two-link inverse kinematics (law of cosines, not the spec's Craig
formulas), the point-mass kinetic energy and the three-link Gauss-Newton solve are written
below with CasADi / NumPy. Closed loops are integrated by the RK4 loop in this file (checked
once against `robotgen.simulation.tree.run`), with the servo's torque held over each step.
"""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import yaml
from reference import const

SPECS = Path(__file__).resolve().parents[2] / "specs"
HIGH, LOW, REDUNDANT = SPECS / "styx_high_ct.yaml", SPECS / "styx_low_ct.yaml", SPECS / "styx_redundant.yaml"
NOMINAL = np.array([0.0, 0.12, 0.0])
SCI = {"float_kind": lambda v: f"{v:.1e}"}


def spec_data(path: Path) -> dict:
    with open(path) as f:
        return yaml.safe_load(f)


# ---- an independent model of the two-fingered hand (Fig 2.1), from the YAML numbers ----------


def _rot(psi):
    c, s = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


def _params(data: dict, node: str) -> dict[str, float]:
    return {k: const(v) for k, v in data["nodes"][node]["define"]["formulas"]["parameters"].items()}


def _box(data: dict) -> tuple[float, float]:
    planar = data["nodes"]["box"]["define"]["rigid_body"]["planar"]
    return const(planar["mass"]), const(planar["inertia"])


def _contacts(data: dict) -> np.ndarray:
    return np.array(
        [[const(c) for c in p] for p in data["nodes"]["hand"]["attach"]["constraint"]["planar_contacts"]["points"]]
    )


class StyxModel:
    """Box pose x_b = (x, y, psi) -> fingertips (rigid contacts) -> finger angles (absolute,
    elbows outward) -> point masses at the link tips; the box is a planar rigid body.

    Left finger base (-b, 0), right (+b, 0) (Fig 2.1 / the spec's kinematics). Inverse
    kinematics by the law of cosines: th1 = atan2(v, u) +/- acos((D^2 + l1^2 - l2^2)/(2 l1 D)),
    th2 = direction from the elbow to the tip; + (left) and - (right) put the elbows outward."""

    def __init__(self, data: dict):
        self.fingers = [_params(data, "left"), _params(data, "right")]
        self.bases = [np.array([-self.fingers[0]["b"], 0.0]), np.array([self.fingers[1]["b"], 0.0])]
        self.signs = (1.0, -1.0)
        self.mb, self.Ib = _box(data)
        self.points = _contacts(data)
        xb, xd = ca.SX.sym("xb", 3), ca.SX.sym("xd", 3)
        tips = [xb[:2] + _rot(xb[2]) @ ca.DM(p) for p in self.points]
        theta = ca.vertcat(
            *[self._ik(tip, f, base, s) for tip, f, base, s in zip(tips, self.fingers, self.bases, self.signs)]
        )
        A = ca.jacobian(theta, xb)  # theta_dot = A xd (eq 3.3, here J^-1 G^T by the chain rule)
        th, thd = ca.SX.sym("th", 4), ca.SX.sym("thd", 4)
        Mf = self._finger_mass(th)
        T_fingers = 0.5 * ca.dot(thd, Mf @ thd)
        T = ca.substitute(T_fingers, ca.vertcat(th, thd), ca.vertcat(theta, A @ xd))
        T += 0.5 * (self.mb * (xd[0] ** 2 + xd[1] ** 2) + self.Ib * xd[2] ** 2)
        M = ca.hessian(T, xd)[0]  # M~ = d^2 T / d xd^2
        dM = [ca.jacobian(M[:, j], xb) for j in range(3)]  # dM[j][i, k] = d M_ij / d x_k
        C = ca.SX(3, 3)
        for i in range(3):
            for j in range(3):  # Christoffel symbols of the first kind, contracted with xd
                C[i, j] = sum(0.5 * (dM[j][i, k] + dM[k][i, j] - dM[j][k, i]) * xd[k] for k in range(3))
        Mdot = ca.jtimes(M, xb, xd)
        self.model = ca.Function("styx", [xb, xd], [theta, A, M, C, Mdot])
        self.finger_mass = ca.Function("mf", [th], [Mf])
        self.tips = ca.Function("tips", [xb], [ca.vertcat(*tips)])

    @staticmethod
    def _ik(tip, f, base, sign):
        u = tip - ca.DM(base)
        D2 = ca.sumsqr(u)
        alpha = ca.acos((D2 + f["l1"] ** 2 - f["l2"] ** 2) / (2 * f["l1"] * ca.sqrt(D2)))
        th1 = ca.atan2(u[1], u[0]) + sign * alpha
        th2 = ca.atan2(u[1] - f["l1"] * ca.sin(th1), u[0] - f["l1"] * ca.cos(th1))
        return ca.vertcat(th1, th2)

    def _finger_mass(self, th):
        """Joint-space M of both fingers from the point masses' kinetic energy."""
        blocks = []
        for k, (f, base) in enumerate(zip(self.fingers, self.bases)):
            q = th[2 * k : 2 * k + 2]
            p1 = ca.DM(base) + f["l1"] * ca.vertcat(ca.cos(q[0]), ca.sin(q[0]))
            p2 = p1 + f["l2"] * ca.vertcat(ca.cos(q[1]), ca.sin(q[1]))
            J1, J2 = ca.jacobian(p1, q), ca.jacobian(p2, q)
            blocks.append(f["m1"] * J1.T @ J1 + f["m2"] * J2.T @ J2)
        return ca.diagcat(*blocks)

    def __call__(self, xb, xd=np.zeros(3)):
        theta, A, M, C, Mdot = (np.array(v) for v in self.model(xb, xd))
        return theta.ravel(), A, M, C, Mdot

    def finger_jacobian(self, k: int, q) -> np.ndarray:
        f = self.fingers[k]
        return np.array(
            [
                [-f["l1"] * math.sin(q[0]), -f["l2"] * math.sin(q[1])],
                [f["l1"] * math.cos(q[0]), f["l2"] * math.cos(q[1])],
            ]
        )


def grasp_map(points: np.ndarray, psi: float) -> np.ndarray:
    """G: box wrench (fx, fy, torque) from the fingertip forces (F1x, F1y, F2x, F2y)."""
    c, s = math.cos(psi), math.sin(psi)
    cols = []
    for p in points:
        r = np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]])
        cols += [[1.0, 0.0, -r[1]], [0.0, 1.0, r[0]]]
    return np.array(cols).T


def squeeze_basis(points: np.ndarray, psi: float) -> np.ndarray:
    """H (1 x 4, orthonormal, G H^T = 0), oriented so that a positive internal force pushes
    each fingertip towards the other contact: it squeezes the box."""
    c, s = math.cos(psi), math.sin(psi)
    d = points[1] - points[0]
    e = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])
    e /= np.linalg.norm(e)
    return np.concatenate([e, -e])[None, :] / math.sqrt(2)


def random_poses(rng, n: int) -> np.ndarray:
    return NOMINAL + rng.uniform([-0.02, -0.02, -0.3], [0.02, 0.02, 0.3], size=(n, 3))


# ---- the closed loop: compiled servo step around the compiled true plant ----------------------


def closed_loop(mod, theta, v, desired, dt: float, steps: int, f_i=None):
    """RK4 on (theta, v) with the servo's tau held over each step (zero-order hold). Returns
    t, root positions, desired positions, root velocities v and leaf angles per step."""
    info = mod.info()
    root = info["nodes"][info["root"]]
    n_ext, n_v, n = len(root["coordinates"]), root["nq"], mod.nq
    zero_tau = np.zeros(n)
    stateful = hasattr(mod, "servo_init")
    state = mod.servo_init(theta, mod.plant_dynamics(theta, v, zero_tau)[0]) if stateful else None

    def pad(a):
        out = np.zeros(n_v)
        out[: len(a)] = a
        return out

    T, X, XD, V, TH = [], [], [], [], []
    for k in range(steps + 1):
        t = k * dt
        x_d, v_d, a_d = desired(t)
        theta_dot = mod.plant_dynamics(theta, v, zero_tau)[0]
        args = [theta, theta_dot, x_d, pad(v_d), pad(a_d), np.zeros(n_v)]
        if root["internal_forces"]:
            args.append(np.zeros(len(root["internal_forces"])) if f_i is None else np.asarray(f_i, float))
        if stateful:
            tau, state = mod.servo_step(*args, state, np.array([dt]))
        else:
            tau = mod.servo_step(*args)
        T.append(t)
        X.append(mod.plant_position(theta)[:n_ext])
        XD.append(x_d)
        V.append(v)
        TH.append(theta)
        if k == steps:
            break

        def f(th, vel):
            return mod.plant_dynamics(th, vel, tau)

        k1 = f(theta, v)
        k2 = f(theta + dt / 2 * k1[0], v + dt / 2 * k1[1])
        k3 = f(theta + dt / 2 * k2[0], v + dt / 2 * k2[1])
        k4 = f(theta + dt * k3[0], v + dt * k3[1])
        theta = theta + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        assert np.all(np.isfinite(theta)) and np.all(np.isfinite(v)), f"diverged at t = {t}"
    return np.array(T), np.array(X), np.array(XD), np.array(V), np.array(TH)


def sinusoid(data: dict, x0: np.ndarray):
    """The spec's desired trajectory x_d(t) = x0 + a sin(2 pi f t), read from its YAML."""
    sim = data["simulation"]
    a = np.array([const(c) for c in sim["amplitude"]])
    w = 2 * np.pi * np.array([const(c) for c in sim["frequency"]])
    return lambda t: (x0 + a * np.sin(w * t), a * w * np.cos(w * t), -a * w * w * np.sin(w * t))


# ---- modules, each built once --------------------------------------------------------------


@pytest.fixture(scope="module")
def high(build_module):
    return build_module(HIGH)


@pytest.fixture(scope="module")
def low(build_module):
    return build_module(LOW)


@pytest.fixture(scope="module")
def redundant(build_module):
    return build_module(REDUNDANT)


@pytest.fixture(scope="module")
def styx():
    return StyxModel(spec_data(HIGH))


# ---- 1. Appendix A: RobotMass[HighCThand] is zero, RobotMass[LowCThand] is the box -----------


def test_appendix_a_masses(high, low, styx):
    rng = np.random.default_rng(10)
    mb, Ib = _box(spec_data(LOW))
    assert (mb, Ib) == (0.2, pytest.approx(0.2 * (0.1**2 + 0.06**2) / 12))
    for xb in random_poses(rng, 10):
        theta = styx(xb)[0]
        theta_dot = rng.normal(size=4)
        np.testing.assert_array_equal(high.ct_hand_mass(theta), np.zeros((3, 3)))
        np.testing.assert_array_equal(high.ct_hand_coriolis(theta, theta_dot), np.zeros((3, 3)))
        # the low-level CT hand: controlled fingers are massless, only the box is left
        np.testing.assert_allclose(low.hand_mass(theta), np.diag([mb, mb, Ib]), rtol=0, atol=1e-15)
        np.testing.assert_allclose(low.hand_coriolis(theta, theta_dot), np.zeros((3, 3)), atol=1e-15)
        np.testing.assert_array_equal(low.fingers_mass(theta), np.zeros((4, 4)))
        # while the uncontrolled hand carries the fingers as well
        assert np.linalg.eigvalsh(high.hand_mass(theta) - np.diag([mb, mb, Ib])).min() > 1e-4


# ---- 2. composite attributes of the uncontrolled hand (eqs 3.3-3.6) ----------------------------


def test_composite_mass_and_coriolis_against_kinetic_energy(high, styx):
    rng = np.random.default_rng(2)
    worst = dict(theta=0.0, M=0.0, C=0.0, skew=0.0, skew_fd=0.0, plant=0.0, read=0.0)
    for xb in random_poses(rng, 60):
        xd = rng.normal(size=3) * [0.1, 0.1, 1.0]
        theta, A, M, C, Mdot = styx(xb, xd)
        theta_dot = A @ xd  # consistent with the grasp constraint
        worst["theta"] = max(worst["theta"], np.abs(high.plant_inverse(xb) - theta).max())
        np.testing.assert_allclose(high.left_mass(theta), np.array(styx.finger_mass(theta))[:2, :2], atol=1e-15)
        M_r, C_r = high.hand_mass(theta), high.hand_coriolis(theta, theta_dot)
        worst["M"] = max(worst["M"], np.abs(M_r - M).max())
        worst["C"] = max(worst["C"], np.abs(C_r - C).max())
        S = Mdot - 2 * C_r
        worst["skew"] = max(worst["skew"], np.abs(S + S.T).max())
        h = 1e-6  # robotgen's own M~ differentiated along the constrained path
        Mdot_fd = (high.hand_mass(styx(xb + h * xd)[0]) - high.hand_mass(styx(xb - h * xd)[0])) / (2 * h)
        S = Mdot_fd - 2 * C_r
        worst["skew_fd"] = max(worst["skew_fd"], np.abs(S + S.T).max())
        # the true plant: theta_dot = A v, M~ v_dot + C~ v = A^T tau
        tau = rng.normal(size=4) * 0.05
        th_dot_p, v_dot_p = high.plant_dynamics(theta, xd, tau)
        v_dot = np.linalg.solve(M, A.T @ tau - C @ xd)
        worst["plant"] = max(worst["plant"], np.abs(th_dot_p - theta_dot).max(), np.abs(v_dot_p - v_dot).max())
        x_r, xd_r = high.hand_read(theta, theta_dot)
        worst["read"] = max(worst["read"], np.abs(x_r - xb).max(), np.abs(xd_r - xd).max())
    print(
        "\ncomposite hand, 60 poses, max |robotgen - reference|:", ", ".join(f"{k} {v:.1e}" for k, v in worst.items())
    )
    assert worst["theta"] < 1e-12
    assert worst["M"] < 1e-9 and worst["C"] < 1e-9
    assert worst["skew"] < 1e-9 and worst["skew_fd"] < 1e-7
    assert worst["plant"] < 1e-9 and worst["read"] < 1e-12


# ---- 3. high-level computed torque: linear, critically damped error (§3.4, §4.1) -----------------


def test_high_level_computed_torque_error_decays_at_the_gains_rate(high):
    from robotgen.model.simulation import SimulationSettings
    from robotgen.simulation.tree import run

    data = spec_data(HIGH)
    ct = data["nodes"]["ct_hand"]["control"]
    kp, kv = const(ct["kp"]), const(ct["kv"])
    wn = math.sqrt(kp)
    assert kv == pytest.approx(2 * wn)  # critically damped: e(t) = (e0 + (ed0 + wn e0) t) exp(-wn t)
    sim = data["simulation"]
    start = np.array([const(c) for c in sim["start"]])
    e0 = np.array([const(c) for c in sim["initial_error"]])
    desired = sinusoid(data, start)
    times = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    deviation = {}
    for dt in (1e-4, 1e-3):
        steps = int(round(0.6 / dt))
        theta0 = StyxModel(data)(start + e0)[0]
        v0 = desired(0.0)[1]  # the box starts moving with the desired velocity: ed0 = 0
        t, x, x_d, _, _ = closed_loop(high, theta0, v0, desired, dt, steps)
        if dt == 1e-4:  # the same loop as `robotgen simulate`
            s = SimulationSettings(
                duration=0.6,
                dt=dt,
                start=tuple(start),
                initial_error=tuple(e0),
                amplitude=tuple(const(c) for c in sim["amplitude"]),
                frequency=tuple(const(c) for c in sim["frequency"]),
            )
            res = run(high, s)
            np.testing.assert_allclose(res.x, x, atol=1e-12)
            np.testing.assert_allclose(res.x_d, x_d, atol=1e-15)
        e = x - x_d
        ed0 = np.zeros(3)
        rows = []
        for tt in times:
            k = int(round(tt / dt))
            analytic = (e0 + (ed0 + wn * e0) * tt) * math.exp(-wn * tt)
            rows.append((tt, e[k], analytic, (e[k] - analytic) / np.abs(e0)))
        deviation[dt] = max(np.abs(r[3]).max() for r in rows)
        print(f"\nhigh-level CT, wn = {wn:g} rad/s, dt = {dt:g}: e(t) = x - x_d vs e0 (1 + wn t) exp(-wn t)")
        for tt, got, want, rel in rows:
            print(
                f"  t = {tt:4.2f}  e = {np.array2string(got, precision=4)}  analytic = "
                f"{np.array2string(want, precision=4)}  dev/|e0| = {np.array2string(rel, formatter=SCI)}"
            )
    print(f"  max dev/|e0|: dt 1e-4 {deviation[1e-4]:.2e}, dt 1e-3 {deviation[1e-3]:.2e}")
    # With tau held over dt the loop is exact up to an O(wn dt) zero-order-hold error: 1.8e-4 of
    # |e0| at dt = 1e-4; 1e-3 leaves a 5x margin, while a 5 % error in wn (9.5 rad/s) would
    # already be off by 2.3e-2 |e0| at t = 0.3 s.
    assert deviation[1e-4] < 1e-3
    # and the deviation is the hold's: first order in dt
    assert 5 < deviation[1e-3] / deviation[1e-4] < 20


# ---- 4. low-level computed torque ignores the box (§4.2) -----------------------------------


def _low_with_box(tmp_path_factory, build_module, mass: float, name: str):
    data = spec_data(LOW)
    data["name"] = name
    inertia = mass * (0.1**2 + 0.06**2) / 12  # the same 10 cm x 6 cm block
    data["nodes"]["box"]["define"]["rigid_body"]["planar"] = {"mass": mass, "inertia": inertia}
    path = tmp_path_factory.mktemp(name) / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return build_module(path)


def test_low_level_computed_torque_degrades_with_box_mass(tmp_path_factory, build_module, low):
    data = spec_data(LOW)
    sim = data["simulation"]
    start = np.array([const(c) for c in sim["start"]])
    e0 = np.array([const(c) for c in sim["initial_error"]])
    desired = sinusoid(data, start)
    theta0 = StyxModel(data)(start + e0)[0]
    dt, duration = const(sim["dt"]), const(sim["duration"])
    rms = {}
    modules = {
        0.0: _low_with_box(tmp_path_factory, build_module, 0.0, "styx_low_ct_massless"),
        0.2: low,
        5.0: _low_with_box(tmp_path_factory, build_module, 5.0, "styx_low_ct_heavy"),
    }
    np.testing.assert_allclose(modules[5.0].hand_mass(theta0), np.diag([5.0, 5.0, 5.0 * 0.0136 / 12]), atol=1e-15)
    for mass, mod in modules.items():
        t, x, x_d, _, _ = closed_loop(mod, theta0, desired(0.0)[1], desired, dt, int(round(duration / dt)))
        late = t >= 1.0  # after the initial error's transient
        rms[mass] = np.sqrt(np.mean((x - x_d)[late] ** 2, axis=0))
    print("\nlow-level CT, RMS of x - x_d over t in [1, 3] s (x [m], y [m], psi [rad]):")
    for mass, r in rms.items():
        print(f"  box {mass:3.1f} kg: {np.array2string(r, precision=3)}")
    print(f"  heavy / massless: {np.array2string(rms[5.0] / rms[0.0], precision=0)}")
    assert np.all(rms[0.0] < 2e-5)  # provably exponentially stable with a massless box
    assert np.all(rms[0.0] < rms[0.2]) and np.all(rms[0.2] < rms[5.0])
    assert np.all(rms[5.0] >= 10 * rms[0.0])


# ---- 5. internal forces (§2.2, §5.1) -------------------------------------------------------


def fingertip_forces(styx: StyxModel, theta, tau) -> np.ndarray:
    """F = J^-T tau, finger by finger, from each finger's own two-link Jacobian."""
    return np.concatenate(
        [np.linalg.solve(styx.finger_jacobian(k, theta[2 * k : 2 * k + 2]).T, tau[2 * k : 2 * k + 2]) for k in range(2)]
    )


def test_internal_force_moves_nothing_and_splits_into_box_force_and_squeeze(high, styx):
    rng = np.random.default_rng(5)
    z3, z4 = np.zeros(3), np.zeros(4)
    for xb in [NOMINAL, *random_poses(rng, 4)]:
        theta = styx(xb)[0]
        M = styx(xb)[2]
        G, H = grasp_map(styx.points, xb[2]), squeeze_basis(styx.points, xb[2])
        assert np.abs(G @ H.T).max() < 1e-15 and abs(H @ H.T - 1).max() < 1e-15
        # the root's servo step at rest, on target: a squeeze alone changes no acceleration
        state = high.servo_init(theta, z4)
        x = high.plant_position(theta)
        dt = np.array([1e-3])
        tau0, _ = high.servo_step(theta, z4, x, z3, z3, z3, np.array([0.0]), state, dt)
        tau2, _ = high.servo_step(theta, z4, x, z3, z3, z3, np.array([2.0]), state, dt)
        assert np.abs(tau2 - tau0).max() > 1e-3  # the fingers do push
        a0, a2 = high.plant_dynamics(theta, z3, tau0)[1], high.plant_dynamics(theta, z3, tau2)[1]
        np.testing.assert_allclose(a2, a0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a0, z3, atol=1e-12)
        # the uncontrolled hand's write: box force and squeeze land where they should
        F_box = rng.normal(size=3) * [1.0, 1.0, 0.05]
        tau = high.hand_write(theta, z4, xb, z3, z3, F_box, np.array([2.0]))
        F = fingertip_forces(styx, theta, tau)
        np.testing.assert_allclose(G @ F, F_box, rtol=0, atol=1e-12)
        np.testing.assert_allclose(abs((H @ F)[0]), 2.0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(high.plant_dynamics(theta, z3, tau)[1], np.linalg.solve(M, F_box), atol=1e-10)
    print(
        f"\ninternal force 2.0 at x_b = {xb.round(3)}: fingertip forces {F.round(4)}, G F = {(G @ F).round(4)} "
        f"(box force {F_box.round(4)}), H F = {(H @ F).round(12)} with H oriented to squeeze"
    )


# ---- 6. redundant fingers: internal motion resolved at the controller (§5.2) -----------------


class ThreeLink:
    """Three-link fingers with absolute angles, from the YAML numbers; fingertip by Gauss-Newton."""

    def __init__(self, data: dict):
        self.p = [_params(data, "left"), _params(data, "right")]
        self.bases = [-self.p[0]["b"], self.p[1]["b"]]
        self.points = _contacts(data)

    def tip(self, k: int, q) -> np.ndarray:
        L = np.array([self.p[k]["l1"], self.p[k]["l2"], self.p[k]["l3"]])
        return np.array([self.bases[k] + L @ np.cos(q), L @ np.sin(q)])

    def jacobian(self, k: int, q) -> np.ndarray:
        L = np.array([self.p[k]["l1"], self.p[k]["l2"], self.p[k]["l3"]])
        return np.vstack([-L * np.sin(q), L * np.cos(q)])

    def solve(self, xb) -> np.ndarray:
        c, s = math.cos(xb[2]), math.sin(xb[2])
        guesses = (np.array([1.9, 1.0, 0.0]), np.array([math.pi - 1.9, math.pi - 1.0, math.pi]))
        out = []
        for k, (p, q) in enumerate(zip(self.points, guesses)):
            target = xb[:2] + np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]])
            for _ in range(50):
                err = target - self.tip(k, q)
                if np.linalg.norm(err) < 1e-15:
                    break
                q = q + np.linalg.pinv(self.jacobian(k, q)) @ err  # minimum-norm step
            np.testing.assert_allclose(self.tip(k, q), target, atol=1e-14)
            out.append(q)
        return np.concatenate(out)


def test_redundant_hand_masks_internal_motion_tracks_and_damps_it(redundant):
    info = redundant.info()
    assert info["root"] == "ct_hand"
    assert info["nodes"]["ct_hand"]["internal_motions"] == [] and info["nodes"]["ct_hand"]["internal_forces"] == []
    assert len(info["nodes"]["hand"]["internal_motions"]) == 2 and info["nodes"]["hand"]["nq"] == 5
    assert info["nodes"]["fingers"]["internal_motions"] == ["fingers_m1", "fingers_m2"]
    assert not hasattr(redundant, "plant_inverse")  # no inverse kinematics for 3-link fingers

    data = spec_data(REDUNDANT)
    fingers = ThreeLink(data)
    ct = data["nodes"]["ct_hand"]["control"]
    wn, kv_i = math.sqrt(const(ct["kp"])), const(ct["kv_internal"])
    assert const(ct["kv"]) == pytest.approx(2 * wn)
    # the spec's own theta0 puts the tips on the nominal grasp (by our kinematics)
    theta_spec = np.array([const(c) for c in data["simulation"]["theta0"]])
    np.testing.assert_allclose(
        np.concatenate([fingers.tip(0, theta_spec[:3]), fingers.tip(1, theta_spec[3:])]),
        [-0.05, 0.12, 0.05, 0.12],
        atol=1e-12,
    )

    e0 = np.array([0.005, -0.005, 0.05])
    theta0 = fingers.solve(NOMINAL + e0)
    np.testing.assert_allclose(redundant.plant_position(theta0), NOMINAL + e0, atol=1e-13)
    desired = sinusoid(data, NOMINAL)
    v0 = np.concatenate([desired(0.0)[1], [0.5, -0.3]])  # the fingers start with internal motion
    x0, xd0 = redundant.hand_read(theta0, redundant.plant_dynamics(theta0, v0, np.zeros(6))[0])
    np.testing.assert_allclose(xd0, v0, atol=1e-13)
    assert redundant.ct_hand_read(theta0, redundant.plant_dynamics(theta0, v0, np.zeros(6))[0])[1].shape == (3,)

    dt = 1e-4
    t, x, x_d, V, TH = closed_loop(redundant, theta0, v0, desired, dt, int(round(1.0 / dt)))
    e = x - x_d
    print(
        f"\nredundant hand, dt = {dt:g}: box error vs e0 (1 + wn t) exp(-wn t), internal rates vs v_i0 exp(-{kv_i:g} t)"
    )
    worst_e = worst_i = 0.0
    for tt in (0.1, 0.2, 0.5, 1.0):
        k = int(round(tt / dt))
        theta_dot = redundant.plant_dynamics(TH[k], V[k], np.zeros(6))[0]
        rates = redundant.hand_read(TH[k], theta_dot)[1][3:]  # the hand's internal components
        want_e = e0 * (1 + wn * tt) * math.exp(-wn * tt)
        want_i = v0[3:] * math.exp(-kv_i * tt)
        worst_e = max(worst_e, (np.abs(e[k] - want_e) / np.abs(e0)).max())
        worst_i = max(worst_i, (np.abs(rates - want_i) / np.abs(v0[3:])).max())
        print(
            f"  t = {tt:3.1f}  e = {np.array2string(e[k], precision=3)} (analytic "
            f"{np.array2string(want_e, precision=3)})  rates = {np.array2string(rates, precision=3)} "
            f"(analytic {np.array2string(want_i, precision=3)})"
        )
    print(f"  max dev: box {worst_e:.1e} |e0|, internal rates {worst_i:.1e} |v_i0|")
    assert worst_e < 2e-3
    assert worst_i < 3e-3  # zero-order-hold floor ~1e-3 |v_i0| at dt = 1e-4 (10x larger at 1e-3)
    assert np.all(np.abs(rates) < np.abs(v0[3:]) / 100)  # exp(-5) = 1/148 after 1 s

    # `robotgen simulate`'s loop from our theta0 (the spec's dt): it runs and tracks
    from robotgen.model.simulation import SimulationSettings
    from robotgen.simulation.tree import run

    sim = data["simulation"]
    res = run(
        redundant,
        SimulationSettings(
            duration=2.0,
            dt=const(sim["dt"]),
            start=tuple(NOMINAL),
            theta0=tuple(theta0),
            amplitude=tuple(const(c) for c in sim["amplitude"]),
            frequency=tuple(const(c) for c in sim["frequency"]),
        ),
    )
    late = np.abs(res.error[res.t >= 1.0]).max(axis=0)
    print(
        f"  robotgen.simulation.tree.run, dt = {const(sim['dt']):g}: max |x - x_d| over t in [1, 2] s = "
        f"{np.array2string(late, formatter=SCI)}"
    )
    np.testing.assert_allclose(res.x[0], NOMINAL + e0, atol=1e-13)
    assert np.all(late < [1e-5, 1e-5, 1e-3])

    # the resolved internal force: 1.0 along the grasp's internal direction, nothing on the box
    theta = fingers.solve(NOMINAL)
    z6 = np.zeros(6)
    state = redundant.servo_init(theta, z6)
    tau, _ = redundant.servo_step(theta, z6, NOMINAL, np.zeros(3), np.zeros(3), np.zeros(3), state, np.array([1e-3]))
    F = []
    for k in range(2):  # fingertip force of a redundant finger: (J J^T)^-1 J tau (J K^T = 0)
        J = fingers.jacobian(k, theta[3 * k : 3 * k + 3])
        F.append(np.linalg.solve(J @ J.T, J @ tau[3 * k : 3 * k + 3]))
    F = np.concatenate(F)
    np.testing.assert_allclose(grasp_map(fingers.points, 0.0) @ F, np.zeros(3), atol=1e-12)
    assert abs((squeeze_basis(fingers.points, 0.0) @ F)[0]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(redundant.plant_dynamics(theta, np.zeros(5), tau)[1], np.zeros(5), atol=1e-10)


# ---- 5b. which way a positive internal force acts ------------------------------------------


def test_positive_internal_force_squeezes_the_box(high, redundant, styx):
    """The specs call the grasp's internal force 'the squeeze' (styx_redundant.yaml resolves it
    'to squeeze the box with 1 N'): a positive value must push the fingertips towards each other."""
    z3, z4, z6 = np.zeros(3), np.zeros(4), np.zeros(6)
    theta = styx(NOMINAL)[0]
    tau = high.hand_write(theta, z4, NOMINAL, z3, z3, z3, np.array([2.0]))
    F = fingertip_forces(styx, theta, tau)
    H = squeeze_basis(styx.points, 0.0)
    print(
        f"\nstyx_high_ct, f_i = +2 at the nominal grasp: left fingertip force {F[:2].round(4)}, "
        f"right {F[2:].round(4)}; H_squeeze F = {(H @ F)[0]:.6f}"
    )
    # styx_redundant resolves its internal force to +1.0 ("squeeze the box with 1 N")
    fingers = ThreeLink(spec_data(REDUNDANT))
    th = fingers.solve(NOMINAL)
    tau_r, _ = redundant.servo_step(th, z6, NOMINAL, z3, z3, z3, redundant.servo_init(th, z6), np.array([1e-3]))
    F_r = np.concatenate(
        [
            np.linalg.lstsq(fingers.jacobian(k, th[3 * k : 3 * k + 3]).T, tau_r[3 * k : 3 * k + 3], rcond=None)[0]
            for k in range(2)
        ]
    )
    print(
        f"styx_redundant, resolved f_i = +1: left fingertip force {F_r[:2].round(4)}, right {F_r[2:].round(4)}; "
        f"H_squeeze F = {(H @ F_r)[0]:.6f}"
    )
    assert (H @ F)[0] == pytest.approx(2.0, abs=1e-12), (
        f"positive f_i pulls the box apart: H_squeeze F = {(H @ F)[0]:.6f}"
    )
    assert (H @ F_r)[0] == pytest.approx(1.0, abs=1e-12), f"'squeeze with 1 N' pulls: H_squeeze F = {(H @ F_r)[0]:.6f}"
