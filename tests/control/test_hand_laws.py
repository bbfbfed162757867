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
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rates, rpy_rotation
from robotgen.symbolic.rigid_body.spatial import skew
from robotgen.symbolic.root_laws.hand import Hand, discretise, orientation_error
from robotgen.symbolic.root_laws.resolved_adaptive import HOLD_REGULARISATION, identify, one_step_control, torque_weight

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
    f = function(
        "maps",
        [q, qd, a],
        [hand.jacobian(q), hand.bias(q, qd), hand.joint_rates(q, qd), hand.joint_accelerations(q, qd, a)],
    )
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
    qdd = ca.Function(
        "fd", [hand.sym.q, hand.sym.qd, hand.sym.tau], [hand._accel(hand.sym.q, hand.sym.qd, hand.sym.tau)]
    )(q, qd, u)
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
            np.testing.assert_allclose(Lv[:, k : k + 1], (fp - fm) / (2 * h), rtol=1e-6, atol=1e-7)
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


def rls(n_phi=19, limit=None):
    """eq 37 with directional forgetting on Theta = [A B c] (phi = (x, u, 1))."""
    Theta, P = ca.SX.sym("Theta", 12, n_phi), ca.SX.sym("P", n_phi, n_phi)
    phi, dx, mu, adapt = ca.SX.sym("phi", n_phi), ca.SX.sym("dx", 12), ca.SX.sym("mu"), ca.SX.sym("adapt")
    return ca.Function("rls", [Theta, P, phi, dx, mu, adapt], [*identify(Theta, P, phi, dx, mu, limit, adapt)])


def test_rls_identifies_a_known_system_and_tracks_a_change():
    """From persistent excitation (random inputs) the shared-P RLS of eq 37 finds the A, B, c
    of a stable 12-state, 6-input affine system to 1e-6; after B and c change, directional
    forgetting with mu = 0.8 follows within 1500 samples (to 1e-2), which mu = 1 does not
    (it averages the old data in); adapt = 0 leaves the estimates alone; P stays symmetric."""
    rng = np.random.default_rng(5)
    A_true = 0.9 * np.linalg.qr(rng.normal(size=(12, 12)))[0]
    Theta_true = np.hstack([A_true, rng.normal(size=(12, 6)), rng.normal(size=(12, 1))])
    f = rls()

    def run(Theta_sys, Theta, P, mu, steps, x):
        for _ in range(steps):
            phi = np.r_[x, rng.normal(size=6), 1.0]
            x_next = Theta_sys @ phi
            Theta, P = (np.array(v) for v in f(Theta, P, phi, x_next, mu, 1))
            x = x_next
        return Theta, P, x

    Theta, P, x = run(Theta_true, np.zeros((12, 19)), 1e6 * np.eye(19), 1.0, 300, rng.normal(size=12))
    error = np.abs(Theta - Theta_true).max()
    print(f"\n  RLS, 300 samples, mu = 1: max |[A B c] - true| = {error:.1e}")
    assert error < 1e-6
    np.testing.assert_array_equal(P, P.T)
    changed = Theta_true.copy()
    changed[:, 12] *= 2  # B's first column doubled
    changed[:, 18] += 0.5  # and the offset moved
    Theta2, P2, x2 = run(changed, Theta, P, 0.8, 1500, x)
    rigid, _, _ = run(changed, Theta, P, 1.0, 1500, x)
    print(
        f"  after the change, 1500 samples: |[A B c] - true| = {np.abs(Theta2 - changed).max():.1e} at mu = 0.8, "
        f"{np.abs(rigid - changed).max():.1e} at mu = 1"
    )
    assert np.abs(Theta2 - changed).max() < 1e-2 and np.abs(rigid - changed).max() > 0.1
    frozen = [np.array(v) for v in f(Theta2, P2, rng.normal(size=19), rng.normal(size=12), 0.95, 0)]
    for before, after in zip((Theta2, P2), frozen):
        np.testing.assert_array_equal(before, after)


def test_directional_forgetting_keeps_the_covariance_bounded_in_closed_loop():
    """Closed-loop data: du = -K dx, so phi = (dx, -K dx, 1) spans 13 of 19 directions.
    Eq 37's exponential forgetting divides all of P by mu and its trace grows as mu^-k (the
    windup behind the torque spikes); the directional update changes P only along P phi and
    leaves phi^T P' phi = s / (s + mu) (s = phi^T P phi): P stays bounded. Without the affine
    term and with phi = 0 nothing is updated and nothing is NaN; the trace limit holds P when
    phi is tiny (P then grows along one direction only)."""
    rng = np.random.default_rng(8)
    K = rng.normal(size=(6, 12))
    f = rls()
    mu = 0.99
    P, Theta, P_exp = np.eye(19), np.zeros((12, 19)), np.eye(19)
    for _ in range(2000):
        dx = 1e-3 * rng.normal(size=12)
        phi = np.r_[dx, -K @ dx, 1.0]
        s = phi @ P @ phi
        Theta, P_next = (np.array(v) for v in f(Theta, P, phi, rng.normal(size=12), mu, 1))
        assert abs(phi @ P_next @ phi - s / (s + mu)) < 1e-12 * max(1.0, s)
        P = P_next
        Pphi = P_exp @ phi  # eq 37 as printed
        P_exp = (P_exp - np.outer(Pphi, Pphi) / (phi @ Pphi + mu)) / mu
    print(
        f"\n  2000 closed-loop samples, mu = {mu}: trace P = {np.trace(P):.3g} directional, "
        f"{np.trace(P_exp):.3g} exponential (eq 37)"
    )
    assert np.trace(P) < 2 * 19 and np.linalg.eigvalsh(P).min() > 0
    assert np.trace(P_exp) > 1e6
    no_affine = rls(18, limit=1e4)
    Pv = np.eye(18)
    for k in range(3000):
        phi = np.zeros(18) if k == 0 else 1e-6 * rng.normal(size=18)
        _, Pv = (np.array(v) for v in no_affine(np.zeros((12, 18)), Pv, phi, np.zeros(12), 0.9, 1))
        assert np.all(np.isfinite(Pv))
    assert np.trace(Pv) <= 1e4 * (1 + 1e-12) and np.linalg.eigvalsh(Pv).min() > -1e-12 * np.trace(Pv)


def test_one_step_control_minimises_eq_38():
    """du* of eq 39 with the holding torque u_c against a numerical minimisation of
    x'^T Q x' + (u - u_c)^T R (u - u_c), x' = A dx + B u + c, u_c = -(B^T Q B + delta R)^-1
    B^T Q c: full symmetric positive definite Q and R, and the rule R = kappa B0^T Q B0.
    u_c leaves only what B cannot reach (up to delta), and stays bounded as B tends to 0."""
    rng = np.random.default_rng(6)
    A, B, c, x = ca.SX.sym("A", 12, 12), ca.SX.sym("B", 12, 6), ca.SX.sym("c", 12), ca.SX.sym("x", 12)
    Q, R, B0, kappa = ca.SX.sym("Q", 12, 12), ca.SX.sym("R", 6, 6), ca.SX.sym("B0", 12, 6), ca.SX.sym("kappa")
    given = ca.Function("u", [A, B, c, x, Q, R], [one_step_control(A, B, c, x, Q, R)])
    rule = ca.Function("R", [Q, B0, kappa], [torque_weight(Q, None, kappa, B0)])
    for _ in range(5):
        Av, Bv, cv, xv = rng.normal(size=(12, 12)), rng.normal(size=(12, 6)), rng.normal(size=12), rng.normal(size=12)
        L, M = rng.normal(size=(12, 12)), rng.normal(size=(6, 6))
        Qv, kv = L @ L.T + 0.1 * np.eye(12), rng.uniform(0.2, 3)
        B0v = Bv + 0.1 * rng.normal(size=(12, 6))
        Rrule = np.array(rule(Qv, B0v, kv))
        np.testing.assert_allclose(Rrule, kv * B0v.T @ Qv @ B0v, rtol=1e-12)
        for Rv in (M @ M.T + 0.1 * np.eye(6), Rrule):
            H = Bv.T @ Qv @ Bv
            u_c = -np.linalg.solve(H + HOLD_REGULARISATION * Rv, Bv.T @ Qv @ cv)
            u_star = np.array(given(Av, Bv, cv, xv, Qv, Rv)).ravel()
            np.testing.assert_allclose(u_star, u_c - np.linalg.solve(H + Rv, Bv.T @ Qv @ Av @ xv), rtol=1e-9)
            exact_hold = -np.linalg.solve(H, Bv.T @ Qv @ cv)

            def cost(u, hold, c):
                x1 = Av @ xv + Bv @ u + c
                return x1 @ Qv @ x1 + (u - hold) @ Rv @ (u - hold)

            # without c, eq 39 is the minimiser of eq 38; with it, up to the regularisation
            u_free = np.array(given(Av, Bv, 0 * cv, xv, Qv, Rv)).ravel()
            found = minimize(cost, np.zeros(6), (np.zeros(6), 0 * cv), method="BFGS", options={"gtol": 1e-10}).x
            assert cost(u_free, np.zeros(6), 0 * cv) <= cost(found, np.zeros(6), 0 * cv) + 1e-9
            np.testing.assert_allclose(u_free, found, atol=1e-5)
            found = minimize(cost, np.zeros(6), (exact_hold, cv), method="BFGS", options={"gtol": 1e-10}).x
            assert np.abs(u_star - found).max() < 1e-5 + 10 * HOLD_REGULARISATION * np.abs(exact_hold).max()
            # at dx = 0 the holding torque leaves what B cannot reach, up to the regularisation:
            # B^T Q x' = -delta R u_c
            at_rest = np.array(given(Av, Bv, cv, np.zeros(12), Qv, Rv)).ravel()
            np.testing.assert_allclose(
                Bv.T @ Qv @ (Bv @ at_rest + cv),
                -HOLD_REGULARISATION * Rv @ at_rest,
                atol=1e-9 * np.abs(Bv.T @ Qv @ cv).max(),
            )
        tiny = np.array(given(Av, 1e-9 * Bv, cv, np.zeros(12), Qv, Rrule)).ravel()
        assert np.all(np.isfinite(tiny)) and np.abs(tiny).max() < 1e-3  # an arm held fast: no runaway


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
