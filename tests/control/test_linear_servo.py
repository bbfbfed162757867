"""The optimal linear servo (robotgen.numeric.linear_servo; Whitney 1972's "optimal linear servo
theory"): closed forms of the scalar and double-integrator cases, a direct minimisation of the
same cost over the whole horizon, optimality against other laws, and the emitted servo_step."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse.linalg import spsolve

from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.numeric.linear_servo import costate, design, finite_horizon

DOUBLE_A = np.array([[0.0, 1.0], [0.0, 0.0]])
DOUBLE_B = np.array([[0.0], [1.0]])
POSITION = np.array([[1.0, 0.0]])


def closed_loop_cost(A, B, C, Q, R, gains, feedforward, reference, x0, h):
    """RK4 on xdot = A x + B u, u = -K x + v, with K, v on the half grid (index i = 2k, 2k+1,
    2k+2 for t_k, t_k + h/2, t_(k+1)); the cost int (Cx - r)^T Q (Cx - r) + u^T R u dt is
    integrated with the state. Returns (x at the nodes, u at the nodes, cost)."""
    n = A.shape[0]
    steps = (len(feedforward) - 1) // 2

    def rates(i, z):
        x = z[:n]
        u = -gains(i) @ x + feedforward[i]
        e = C @ x - reference(0.5 * h * i)
        return np.r_[A @ x + B @ u, e @ Q @ e + u @ R @ u], u

    z = np.r_[x0, 0.0]
    X, U = [], []
    for k in range(steps + 1):
        k1, u = rates(2 * k, z)
        X.append(z[:n])
        U.append(u)
        if k == steps:
            break
        k2, _ = rates(2 * k + 1, z + h / 2 * k1)
        k3, _ = rates(2 * k + 1, z + h / 2 * k2)
        k4, _ = rates(2 * k + 2, z + h * k3)
        z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(X), np.array(U), float(z[-1])


def transcription(A, B, C, Q, R, F, reference, x0, t_end, h):
    """The finite-horizon cost minimised directly over the states and inputs at every node:
    trapezoidal dynamics and cost, one sparse KKT solve. Returns (u (N+1, m), cost)."""
    nx, nu = B.shape
    N = int(round(t_end / h))
    r = np.array([reference(k * h) for k in range(N + 1)])
    w = np.full(N + 1, h)
    w[[0, -1]] = h / 2
    nz = (N + 1) * (nx + nu)
    H = sparse.lil_matrix((nz, nz))
    c = np.zeros(nz)
    CtQC, CtQ = C.T @ Q @ C, C.T @ Q
    for k in range(N + 1):
        z = k * (nx + nu)
        H[z : z + nx, z : z + nx] = 2 * w[k] * CtQC
        H[z + nx : z + nx + nu, z + nx : z + nx + nu] = 2 * w[k] * R
        c[z : z + nx] = -2 * w[k] * CtQ @ r[k]
    z = N * (nx + nu)
    H[z : z + nx, z : z + nx] += 2 * C.T @ F @ C
    c[z : z + nx] -= 2 * C.T @ F @ r[-1]
    E = sparse.lil_matrix((nx * (N + 1), nz))
    E[:nx, :nx] = np.eye(nx)
    for k in range(N):
        row, z = nx * (k + 1), k * (nx + nu)
        E[row : row + nx, z : z + nx + nu] = np.hstack([np.eye(nx) + h / 2 * A, h / 2 * B])
        E[row : row + nx, z + nx + nu : z + 2 * (nx + nu)] = np.hstack([-np.eye(nx) + h / 2 * A, h / 2 * B])
    kkt = sparse.bmat([[H, E.T], [E, None]], format="csc")
    sol = spsolve(kkt, np.r_[-c, x0, np.zeros(nx * N)])[:nz].reshape(N + 1, nx + nu)
    x, u = sol[:, :nx], sol[:, nx:]
    e = x @ C.T - r
    cost = np.einsum("k,ki,ij,kj->", w, e, Q, e) + np.einsum("k,ki,ij,kj->", w, u, R, u) + e[-1] @ F @ e[-1]
    return u, float(cost)


# -- closed forms --------------------------------------------------------------------------
def test_scalar_servo_matches_the_closed_form():
    """xdot = a x + b u, y = x: lambda = sqrt(a^2 + b^2 q / rho), P = rho (a + lambda) / b^2,
    A_c = -lambda; for r = sin(w t), gdot = lambda g - q r has the particular solution
    q (lambda sin + w cos) / (lambda^2 + w^2), plus exp(-lambda (tf - t)) times the gap to the
    held g_f = q r(tf) / lambda at tf."""
    a, b, q, rho, w, tf = 0.5, 2.0, 9.0, 0.25, 3.0, 2.0
    lam = np.sqrt(a * a + b * b * q / rho)
    servo = design([[a]], [[b]], [[1.0]], [[q]], [[rho]])
    assert servo.P[0, 0] == pytest.approx(rho * (a + lam) / b**2, rel=1e-14)
    assert servo.closed[0, 0] == pytest.approx(-lam, rel=1e-14)

    def reference(t):
        return np.array([np.sin(w * t)])

    assert servo.held_costate(reference(tf))[0] == pytest.approx(q * np.sin(w * tf) / lam, rel=1e-14)

    def particular(t):
        return q * (lam * np.sin(w * t) + w * np.cos(w * t)) / (lam**2 + w**2)

    gaps = []
    for steps in (200, 400):
        t, g = costate(servo, reference, 0.0, tf, steps)
        exact = particular(t) + np.exp(-lam * (tf - t)) * (q * np.sin(w * tf) / lam - particular(tf))
        gaps.append(np.abs(g[:, 0] - exact).max())
    print(f"\nscalar servo: costate error {gaps[0]:.2e} (h = 10 ms), {gaps[1]:.2e} (5 ms)")
    assert gaps[1] < 1e-8
    assert 12 < gaps[0] / gaps[1] < 20  # RK4: fourth order


def test_scalar_finite_horizon_riccati_matches_the_closed_form():
    """With P(tf) = 0, dP/dtau = -(b^2/rho)(P - P+)(P - P-), tau = tf - t, P+- = rho (a +- lambda)
    / b^2, so (P - P+)/(P - P-) = (P+/P-) exp(-2 lambda tau)."""
    a, b, q, rho, tf = -0.3, 1.5, 4.0, 0.5, 1.5
    lam = np.sqrt(a * a + b * b * q / rho)
    plus, minus = rho * (a + lam) / b**2, rho * (a - lam) / b**2
    fh = finite_horizon([[a]], [[b]], [[1.0]], [[q]], [[rho]], lambda t: np.array([1.0]), 0.0, tf, 600)
    ratio = plus / minus * np.exp(-2 * lam * (tf - fh.times))
    exact = (plus - ratio * minus) / (1 - ratio)
    print(
        f"\nscalar Riccati: max |P - closed form| {np.abs(fh.P[:, 0, 0] - exact).max():.2e}, P(0) "
        f"{fh.P[0, 0, 0]:.12f} against the steady {plus:.12f}"
    )
    np.testing.assert_allclose(fh.P[:, 0, 0], exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fh.K[:, 0, 0], b / rho * exact, rtol=0, atol=1e-8)


def test_double_integrator_follows_a_ramp_without_lag():
    """K = (sqrt(q/rho), sqrt(2 sqrt(q/rho))) in closed form. Following r = c t, the servo's
    error dies out (y = c t with u = 0 costs nothing), while the same gains on the error alone,
    u = -K1 (y - r) - K2 ydot, settle at the lag y - r = -K2 c / K1."""
    q, rho, c, tf, h = 1600.0, 1.0, 0.3, 10.0, 1e-3
    servo = design(DOUBLE_A, DOUBLE_B, POSITION, [[q]], [[rho]])
    k1 = np.sqrt(q / rho)
    np.testing.assert_allclose(servo.K, [[k1, np.sqrt(2 * k1)]], rtol=1e-13)

    def reference(t):
        return np.array([c * t])

    steps = int(round(tf / h))
    _, g = costate(servo, reference, 0.0, tf, 2 * steps)
    x, _, _ = closed_loop_cost(
        DOUBLE_A,
        DOUBLE_B,
        POSITION,
        np.array([[q]]),
        np.array([[rho]]),
        lambda i: servo.K,
        servo.feedforward(g),
        reference,
        np.zeros(2),
        h,
    )
    feedback = np.array([[k1 * c * 0.5 * h * i] for i in range(2 * steps + 1)])  # K1 r: the error-only law
    y, _, _ = closed_loop_cost(
        DOUBLE_A,
        DOUBLE_B,
        POSITION,
        np.array([[q]]),
        np.array([[rho]]),
        lambda i: servo.K,
        feedback,
        reference,
        np.zeros(2),
        h,
    )
    mid = steps // 2
    servo_error = x[mid, 0] - c * mid * h
    lag = y[mid, 0] - c * mid * h
    print(
        f"\nramp at t = {mid * h:g} s: servo error {servo_error:.2e}, error-only lag {lag:.6f} "
        f"(closed form {-servo.K[0, 1] * c / k1:.6f})"
    )
    assert abs(servo_error) < 1e-9
    assert lag == pytest.approx(-servo.K[0, 1] * c / k1, abs=1e-9)


# -- optimality ----------------------------------------------------------------------------
def test_finite_horizon_servo_is_the_direct_minimum():
    """The finite-horizon servo (time-varying P and g) against the same cost minimised
    directly over the whole horizon (trapezoidal transcription at 10, 5 and 2.5 ms,
    extrapolated): the costs and the inputs agree; the steady servo and the gains on the error
    alone cost more. The transcription's cost error is a h^2 + b h^3 + ... (the h^3 from its
    end nodes, whose inputs are off by O(h): half a step of the adjoint equation there), so
    two Richardson steps remove both; the inputs are compared inside the horizon."""
    A = np.array([[0.0, 1.0], [-2.0, -0.4]])  # a damped spring, so that the free response matters
    B = np.array([[0.0], [1.5]])
    C, Q, R, F = POSITION, np.array([[50.0]]), np.array([[0.2]]), np.array([[20.0]])
    tf, h = 3.0, 1e-3
    x0 = np.array([0.2, 0.0])

    def reference(t):
        return np.array([np.sin(2 * t) + 0.5 * t])

    steps = int(round(tf / h))
    fh = finite_horizon(A, B, C, Q, R, reference, 0.0, tf, 2 * steps, F)
    _, u, running = closed_loop_cost(A, B, C, Q, R, lambda i: fh.K[i], fh.v, reference, x0, h)
    x_end = closed_loop_cost(A, B, C, Q, R, lambda i: fh.K[i], fh.v, reference, x0, h)[0][-1]
    e_end = C @ x_end - reference(tf)
    servo_cost = running + e_end @ F @ e_end

    coarse, fine, finest = (transcription(A, B, C, Q, R, F, reference, x0, tf, step) for step in (0.01, 0.005, 0.0025))
    once = [(4 * b[1] - a[1]) / 3 for a, b in ((coarse, fine), (fine, finest))]  # h^2 gone
    direct_cost = (8 * once[1] - once[0]) / 7  # h^3 gone
    direct_u = (4 * fine[0][::2] - coarse[0]) / 3
    gap_u = np.abs(direct_u - u[::10])[1:-1].max()
    print(
        f"\nfinite horizon: servo cost {servo_cost:.10f}, direct {direct_cost:.10f} (at 10 ms alone "
        f"{coarse[1]:.10f}, after one Richardson step {once[1]:.10f}); inputs within {gap_u:.2e} "
        f"(peak {np.abs(u).max():.3f})"
    )
    assert abs(direct_cost - servo_cost) < 1e-8 * servo_cost
    assert abs(once[1] - servo_cost) > 10 * abs(direct_cost - servo_cost)  # each step converges
    assert gap_u < 1e-5 * np.abs(u).max()

    steady = design(A, B, C, Q, R)
    _, g = costate(steady, reference, 0.0, tf, 2 * steps)
    others = {
        "steady servo": (lambda i: steady.K, steady.feedforward(g)),
        "error-only gains": (
            lambda i: fh.K[i],
            np.array([fh.K[i] @ np.r_[reference(0.5 * h * i), 0.0] for i in range(2 * steps + 1)]),
        ),
    }
    for label, (gains, v) in others.items():
        x, _, running = closed_loop_cost(A, B, C, Q, R, gains, v, reference, x0, h)
        e_end = C @ x[-1] - reference(tf)
        cost = running + e_end @ F @ e_end
        print(f"{label}: cost {cost:.6f}")
        assert cost > servo_cost * (1 + 1e-6)


def test_feedforward_shape_and_grid_checks():
    servo = design(DOUBLE_A, DOUBLE_B, POSITION, [[1.0]], [[1.0]])
    with pytest.raises(ValueError, match="the reference has 2 entries"):
        costate(servo, lambda t: np.zeros(2), 0.0, 1.0, 10)
    with pytest.raises(ValueError, match="tf > t0"):
        costate(servo, lambda t: np.zeros(1), 1.0, 1.0, 10)
    t, g = costate(servo, lambda t: np.ones(1), 0.0, 1.0, 10)
    assert t.shape == (11,) and g.shape == (11, 2) and servo.feedforward(g).shape == (11, 1)


# -- the emitted servo_step --------------------------------------------------------------------
SERVO_SPEC = """robotgen: 1
name: {name}
root: ctl
nodes:
  ctl:
    control:
      robot: arm
      law: resolved_rate
      resolved_rate:
        frame: base
        free: [z, rx, ry, rz]
        lqr: {{nominal: [0.3, 0.6], q: [400, 4], r: [1, 2], servo: {servo}}}
  arm:
    define:
      chain:
        convention: joints
        gravity: [0, -9.81, 0]
        joints:
          - {{name: shoulder, type: revolute, axis: [0, 0, 1], link: {{mass: 1.2, com: [0.3, 0, 0], inertia: {{ixx: 0.001, iyy: 0.04, izz: 0.04}}}}, friction: {{viscous: 0.1}}}}
          - {{name: elbow, type: revolute, axis: [0, 0, 1], origin: {{xyz: [0.6, 0, 0]}}, link: {{mass: 0.9, com: [0.25, 0, 0], inertia: {{ixx: 0.001, iyy: 0.02, izz: 0.02}}}}, friction: {{viscous: 0.1}}}}
        tool: {{xyz: [0.5, 0, 0]}}
"""


def test_servo_step_is_lqr_step_plus_the_feedforward(build_module, tmp_path):
    spec = tmp_path / "servo_two_link.yaml"
    spec.write_text(SERVO_SPEC.format(name="servo_two_link", servo="true"))
    arm = build_module(spec)
    assert "servo_step" in arm.info()["functions"]
    lqr = arm.lqr
    A, B, K = (np.array(lqr[k]) for k in ("A", "B", "K"))
    servo = design(A, B, np.eye(4), np.diag(lqr["Q"]), np.diag(lqr["R"]))
    assert np.array_equal(servo.K, K)  # the same Riccati solve, to the bit
    rng = np.random.default_rng(7)
    q, qd, v = rng.uniform(-1, 1, (3, 50, 2))
    np.testing.assert_allclose(arm.servo_step(q, qd, v), arm.lqr_step(q, qd) + v, rtol=0, atol=1e-12)
    expected = np.array(lqr["tau0"]) - np.hstack([q - np.array(lqr["nominal"]), qd]) @ K.T + v
    np.testing.assert_allclose(arm.servo_step(q, qd, v), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("servo, message", [("3", "true or false"), ("yes please", "true or false")])
def test_servo_setting_is_checked_with_its_place(tmp_path, servo, message):
    spec = tmp_path / "bad_servo.yaml"
    spec.write_text(SERVO_SPEC.format(name="bad_servo", servo=servo))
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    print(f"\n{text}")
    assert message in text and f"{spec}:12:" in text and "lqr.servo" in text
