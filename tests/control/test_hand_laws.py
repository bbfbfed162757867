"""The pieces of resolved acceleration and resolved motion adaptive control (Lee and Lee 1983)
against independent references: forward maps, finite differences, a brute-force minimiser,
and known linear systems. Graphs are evaluated with CasADi (what the C is printed from)."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
from scipy.linalg import expm
from scipy.optimize import minimize

from robotgen.frontend import load_system
from robotgen.symbolic.control.hand import Hand, discretise, orientation_error
from robotgen.symbolic.control.resolved_adaptive import identify, one_step_control
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rates, rpy_rotation
from robotgen.symbolic.rigid_body.spatial import skew

ROOT = Path(__file__).resolve().parents[2]
RMAC = ROOT / "specs" / "puma560_rmac.yaml"


def puma_hand() -> Hand:
    system = load_system(str(RMAC))
    return Hand(system.nodes[system.root_node.robot].leaf, system.root_node.hand.tool)


def function(name, inputs, outputs):
    return ca.Function(name, inputs, outputs)


def states(rng, n=20):
    """Random joint states away from the PUMA's singularities (|det J| checked)."""
    hand = puma_hand()
    J = function("J", [hand.sym.q], [hand.jacobian(hand.sym.q)])
    out = []
    while len(out) < n:
        q = rng.uniform(-np.pi, np.pi, 6)
        if abs(np.linalg.det(np.array(J(q)))) > 1e-2:
            out.append((q, rng.normal(size=6), rng.normal(size=6)))
    return hand, out


def test_resolved_rates_and_accelerations_invert_the_forward_maps():
    """qd = J^-1 twist (eq 11) gives back the twist, and qdd from eq 13 the hand
    acceleration J qdd + Jdot qd (eq 10)."""
    hand, cases = states(np.random.default_rng(1))
    q, qd, a = (ca.SX.sym(s, 6) for s in ("q", "qd", "a"))
    f = function("maps", [q, qd, a], [hand.jacobian(q), hand.bias(q, qd), hand.joint_rates(q, qd),
                                      hand.joint_accelerations(q, qd, a)])
    worst = 0.0
    for qv, twist, accel in cases:
        J, bias, rates, _ = (np.array(v) for v in f(qv, twist, accel))
        J2, bias2, _, qdd = (np.array(v) for v in f(qv, rates.ravel(), accel))
        worst = max(worst, np.abs(J @ rates - twist[:, None]).max(), np.abs(J2 @ qdd + bias2 - accel[:, None]).max())
    print(f"\n  eq 11 and eq 13 against the forward maps, 20 states: {worst:.1e}")
    assert worst < 1e-10


def test_euler_rate_map_matches_finite_differences():
    """d(roll, pitch, yaw)/dt of R(t) = exp(t [omega x]) R0 equals rpy_rates(rpy, omega) (eq 7,
    re-derived), and the angles read back the rotation they came from (eq 2)."""
    rpy, w = ca.SX.sym("rpy", 3), ca.SX.sym("w", 3)
    rates = function("rates", [rpy, w], [rpy_rates(rpy, w)])
    R = ca.SX.sym("R", 3, 3)
    angles = function("angles", [R], [rpy_of(R)])
    rotation = function("rotation", [rpy], [rpy_rotation(rpy)])
    rng = np.random.default_rng(2)
    h = 1e-6
    worst = worst_back = 0.0
    for _ in range(50):
        phi = rng.uniform([-3, -1.4, -3], [3, 1.4, 3])
        omega = rng.normal(size=3)
        R0 = np.array(rotation(phi))
        worst_back = max(worst_back, np.abs(np.array(angles(R0)).ravel() - phi).max())
        plus = np.array(angles(expm(h * np.array(ca.DM(skew(ca.DM(omega))))) @ R0)).ravel()
        minus = np.array(angles(expm(-h * np.array(ca.DM(skew(ca.DM(omega))))) @ R0)).ravel()
        fd = (plus - minus) / (2 * h)
        worst = max(worst, np.abs(fd - np.array(rates(phi, omega)).ravel()).max())
    print(f"\n  Euler-rate map vs central differences: {worst:.1e}; angles read back: {worst_back:.1e}")
    assert worst < 1e-7 and worst_back < 1e-12


def test_linearised_hand_dynamics_match_finite_differences():
    """F = df/dx and L = df/du (eqs 24-28) against central differences of the hand-space
    equations (eq 19) along joint-space perturbations mapped through x(q, qd)."""
    hand, cases = states(np.random.default_rng(3), n=3)
    q, qd, u = (ca.SX.sym(s, 6) for s in ("q", "qd", "u"))
    qdd = ca.Function("fd", [hand.sym.q, hand.sym.qd, hand.sym.tau], [hand._accel(hand.sym.q, hand.sym.qd, hand.sym.tau)])(q, qd, u)
    F, L = hand.linearisation(q, qd, qdd)  # at the acceleration the torques u give
    f = function("f", [q, qd, u], [hand.hand_dynamics(q, qd, u), hand.state(q, qd), F, L])
    h = 1e-6
    for qv, qdv, uv in cases:
        uv = 10 * uv
        f0, x0, Fv, Lv = (np.array(v) for v in f(qv, qdv, uv))
        for k in range(6):  # L column by column
            e = np.zeros(6)
            e[k] = h
            fp, fm = np.array(f(qv, qdv, uv + e)[0]), np.array(f(qv, qdv, uv - e)[0])
            np.testing.assert_allclose(Lv[:, k:k + 1], (fp - fm) / (2 * h), rtol=1e-6, atol=1e-7)
        for k in range(12):  # F applied to the state change of a joint perturbation
            dz = np.zeros(12)
            dz[k] = h
            fp, xp = (np.array(v) for v in f(qv + dz[:6], qdv + dz[6:], uv)[:2])
            fm, xm = (np.array(v) for v in f(qv - dz[:6], qdv - dz[6:], uv)[:2])
            dx = xp - xm
            dx[3:6] = (dx[3:6] + np.pi) % (2 * np.pi) - np.pi
            np.testing.assert_allclose(Fv @ dx, fp - fm, rtol=1e-5, atol=1e-8)


def test_discretisation_is_the_matrix_exponential():
    rng = np.random.default_rng(4)
    Fv, Lv = rng.normal(size=(4, 4)), rng.normal(size=(4, 2))
    F, L = ca.SX.sym("F", 4, 4), ca.SX.sym("L", 4, 2)
    T = 1e-3
    A, B = discretise(F, L, T)
    Av, Bv = (np.array(v) for v in ca.Function("d", [F, L], [A, B])(Fv, Lv))
    big = expm(np.block([[Fv, Lv], [np.zeros((2, 6))]]) * T)  # Van Loan: [A B; 0 I]
    np.testing.assert_allclose(Av, big[:4, :4], atol=1e-14)
    np.testing.assert_allclose(Bv, big[:4, 4:], atol=1e-14)


def rls():
    """identify() as a function of numbers: (A, B, P, phi, dx, r, limit, adapt) -> (A, B, P)."""
    A, B, P = ca.SX.sym("A", 12, 12), ca.SX.sym("B", 12, 6), ca.SX.sym("P", 18, 18)
    phi, dx, r, adapt = ca.SX.sym("phi", 18), ca.SX.sym("dx", 12), ca.SX.sym("r"), ca.SX.sym("adapt")
    return ca.Function("rls", [A, B, P, phi, dx, r, adapt], [*identify(A, B, P, phi, dx, r, 1e12, adapt)])


def test_rls_identifies_a_known_system_and_tracks_a_change():
    """From persistent excitation (random inputs) the shared-P RLS of eq 37 finds the A, B of
    a stable 12-state, 6-input system to 1e-6; with r = 0.95 it follows a step change of B
    within 500 samples, which r = 1 does not; adapt = 0 leaves the estimates alone; P stays
    symmetric."""
    rng = np.random.default_rng(5)
    A_true = 0.9 * np.linalg.qr(rng.normal(size=(12, 12)))[0]
    B_true = rng.normal(size=(12, 6))
    f = rls()

    def run(A_sys, B_sys, A, B, P, r, steps, x):
        for _ in range(steps):
            u = rng.normal(size=6)
            x_next = A_sys @ x + B_sys @ u
            A, B, P = (np.array(v) for v in f(A, B, P, np.r_[x, u], x_next, r, 1))
            x = x_next
        return A, B, P, x

    A, B, P, x = run(A_true, B_true, np.zeros((12, 12)), np.zeros((12, 6)), 1e6 * np.eye(18), 1.0, 300,
                     rng.normal(size=12))
    error = max(np.abs(A - A_true).max(), np.abs(B - B_true).max())
    print(f"\n  RLS, 300 samples, r = 1: max |[A B] - true| = {error:.1e}")
    assert error < 1e-6
    np.testing.assert_array_equal(P, P.T)
    B_changed = B_true.copy()
    B_changed[:, 0] *= 2
    A2, B2, P2, x2 = run(A_true, B_changed, A, B, P, 0.95, 500, x)
    _, B_rigid, _, _ = run(A_true, B_changed, A, B, P, 1.0, 500, x)
    print(f"  after B's first column doubled, 500 samples: |B - true| = {np.abs(B2 - B_changed).max():.1e} "
          f"at r = 0.95, {np.abs(B_rigid - B_changed).max():.1e} at r = 1")
    assert np.abs(B2 - B_changed).max() < 1e-6 < np.abs(B_rigid - B_changed).max()
    frozen = [np.array(v) for v in f(A2, B2, P2, rng.normal(size=18), rng.normal(size=12), 0.95, 0)]
    for before, after in zip((A2, B2, P2), frozen):
        np.testing.assert_array_equal(before, after)


def test_covariance_stays_bounded_without_excitation():
    """r < 1 and no excitation: P would grow as r^-k; its trace is held at the limit."""
    A, B, P = ca.SX.sym("A", 12, 12), ca.SX.sym("B", 12, 6), ca.SX.sym("P", 18, 18)
    phi, dx = ca.SX.sym("phi", 18), ca.SX.sym("dx", 12)
    f = ca.Function("rls", [A, B, P, phi, dx], [identify(A, B, P, phi, dx, 0.9, 1e4)[2]])
    Pv = np.eye(18)
    for _ in range(200):
        Pv = np.array(f(np.zeros((12, 12)), np.zeros((12, 6)), Pv, np.zeros(18), np.zeros(12)))
    assert abs(np.trace(Pv) - 1e4) < 1e-6 and np.linalg.eigvalsh(Pv).min() > 0


def test_one_step_control_minimises_eq_38():
    """u* of eq 39 against a numerical minimisation of J = (x'^T Q x' + u^T R u) / 2 with
    x' = A x + B u."""
    rng = np.random.default_rng(6)
    A, B, x = ca.SX.sym("A", 12, 12), ca.SX.sym("B", 12, 6), ca.SX.sym("x", 12)
    q, r = ca.SX.sym("q", 12), ca.SX.sym("r", 6)
    f = ca.Function("u", [A, B, x, q, r], [one_step_control(A, B, x, q, r)])
    for _ in range(5):
        Av, Bv, xv = rng.normal(size=(12, 12)), rng.normal(size=(12, 6)), rng.normal(size=12)
        qv, rv = rng.uniform(0.1, 10, 12), rng.uniform(0.1, 10, 6)
        u_star = np.array(f(Av, Bv, xv, qv, rv)).ravel()

        def cost(u):
            x1 = Av @ xv + Bv @ u
            return 0.5 * (x1 @ (qv * x1) + u @ (rv * u))

        found = minimize(cost, np.zeros(6), method="BFGS", options={"gtol": 1e-10}).x
        assert cost(u_star) <= cost(found) + 1e-9
        np.testing.assert_allclose(u_star, found, atol=1e-5)


def test_orientation_error_is_the_rotation_that_remains():
    """For R_d = exp([a k x]) R the error is sin(a) k (Luh, Walker, Paul)."""
    Rd, R = ca.SX.sym("Rd", 3, 3), ca.SX.sym("R", 3, 3)
    f = ca.Function("e", [Rd, R], [orientation_error(Rd, R)])
    rng = np.random.default_rng(7)
    for _ in range(10):
        k = rng.normal(size=3)
        k /= np.linalg.norm(k)
        angle = rng.uniform(0, 1.5)
        R0 = expm(np.array(ca.DM(skew(ca.DM(rng.normal(size=3))))))
        R_d = expm(angle * np.array(ca.DM(skew(ca.DM(k))))) @ R0
        np.testing.assert_allclose(np.array(f(R_d, R0)).ravel(), np.sin(angle) * k, atol=1e-12)
