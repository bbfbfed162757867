"""The optimal linear servo: tracking a reference known in advance on a linear model
(Whitney 1972, "Dynamic Control of Arms": eq 19 applied to the whole state, "optimal linear
servo theory" of his ref /19/; the linear tracking problem of Athans and Falb, 1966).

Model xdot = A x + B u, output y = C x, reference r(t) on [t0, tf]. Cost

    J = int_t0^tf (y - r)^T Q (y - r) + u^T R u dt + x(tf)^T F x(tf) - 2 phi^T x(tf).

Derivation (ours, by dynamic programming). Try V(x, t) = x^T P x - 2 g^T x + c(t). Then
-V_t = min_u [(Cx - r)^T Q (Cx - r) + u^T R u + V_x^T (A x + B u)], V_x = 2 (P x - g), whose
minimiser is

    u = -R^-1 B^T (P x - g) = -K x + v,   K = R^-1 B^T P,   v = R^-1 B^T g.       (S1)

Put back, with G = B R^-1 B^T, the terms quadratic in x give the Riccati equation and the
terms linear in x give g's equation, both run backwards from tf:

    -Pdot = A^T P + P A - P G P + C^T Q C,        P(tf) = F                      (S2)
     gdot = -(A - G P)^T g - C^T Q r(t),          g(tf) = phi                     (S3)

Steady servo: P is the stabilising solution of the algebraic equation (S2 with Pdot = 0,
robotgen.numeric.riccati), so K is constant and A_c = A - B K is Hurwitz; (S3) with
A_c is then stable backwards in time. For a reference that stays at r_f after tf, the
costate that continues the solution to an infinite horizon is the steady one,

    0 = -A_c^T g_f - C^T Q r_f,                                                   (S4)

and with F = P, phi = g_f the finite problem on [t0, tf] is solved exactly by the constant
P (S2 stays at rest) and g from (S3, S4). Finite-horizon servo: P(t) and g(t) together from
(S2, S3), with F = C^T F_y C and phi = C^T F_y r(tf) for a terminal cost on the output.

g is integrated backwards by classical RK4 over a uniform grid, reading r at the nodes and
midpoints. For the steady servo the step is linear, g_k = T g_(k+1) + h (W0 f_(k+1) +
Wm f_(k+1/2) + W1 f_k) with f = C^T Q r and M = A_c^T,

    T = I + hM + (hM)^2/2 + (hM)^3/6 + (hM)^4/24,
    W0 = (I + hM + (hM)^2/2 + (hM)^3/4) / 6,  Wm = (4 I + 2 hM + (hM)^2/2) / 6,  W1 = I / 6,

which is RK4 expanded for a linear equation (our algebra). Every product is the riccati
module's fixed-order elementwise one, so the costate is the same on every machine.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robotgen.numeric.riccati import _matmul, _solve, solve_care

Reference = Callable[[float], np.ndarray]


@dataclass(frozen=True, eq=False)
class LinearServo:
    """The steady servo of (S1): u = -K x + v(t)."""

    A: np.ndarray  # (nx, nx)
    B: np.ndarray  # (nx, nu)
    C: np.ndarray  # (ny, nx)
    Q: np.ndarray  # (ny, ny)
    R: np.ndarray  # (nu, nu)
    P: np.ndarray  # (nx, nx) stabilising solution of (S2) at rest
    K: np.ndarray  # (nu, nx) = R^-1 B^T P

    @property
    def closed(self) -> np.ndarray:
        """A_c = A - B K."""
        return self.A - _matmul(self.B, self.K)

    def held_costate(self, r: np.ndarray) -> np.ndarray:
        """g_f of (S4) for the reference held at r."""
        return _solve(self.closed.T, -_matmul(_matmul(self.C.T, self.Q), np.reshape(r, (-1, 1))))[:, 0]

    def feedforward(self, g: np.ndarray) -> np.ndarray:
        """v = R^-1 B^T g of (S1), for each row of g."""
        return _matmul(np.atleast_2d(g), _solve(self.R, self.B.T).T)


@dataclass(frozen=True, eq=False)
class FiniteHorizonServo:
    """The finite-horizon servo of (S1-S3) on a uniform grid: u = -K(t) x + v(t)."""

    times: np.ndarray  # (N+1,)
    P: np.ndarray  # (N+1, nx, nx)
    g: np.ndarray  # (N+1, nx)
    K: np.ndarray  # (N+1, nu, nx)
    v: np.ndarray  # (N+1, nu)


def design(A, B, C, Q, R) -> LinearServo:
    """The steady servo for the output y = C x weighted by Q, the input by R."""
    A, B, C, Q, R = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, Q, R))
    P = solve_care(A, B, _matmul(_matmul(C.T, Q), C), R)
    return LinearServo(A, B, C, Q, R, P, _matmul(_solve(R, B.T), P))


def _grid(t0: float, tf: float, steps: int) -> tuple[np.ndarray, float]:
    """The nodes and midpoints t0, t0 + h/2, ..., tf, and h."""
    if steps < 1 or not tf > t0:
        raise ValueError(f"a grid needs tf > t0 and steps >= 1, got [{t0}, {tf}] in {steps}")
    h = (tf - t0) / steps
    return t0 + 0.5 * h * np.arange(2 * steps + 1), h


def _forcing(C: np.ndarray, Q: np.ndarray, reference: Reference, half_grid: np.ndarray) -> np.ndarray:
    """Rows f = C^T Q r(t) at every node and midpoint."""
    r = np.array([np.ravel(reference(float(t))) for t in half_grid], dtype=float)
    if r.shape[1] != C.shape[0]:
        raise ValueError(f"the reference has {r.shape[1]} entries, the output y = C x {C.shape[0]}")
    return _matmul(r, _matmul(Q, C))


def costate(
    servo: LinearServo, reference: Reference, t0: float, tf: float, steps: int
) -> tuple[np.ndarray, np.ndarray]:
    """(times (N+1,), g (N+1, nx)) of the steady servo on [t0, tf]: (S3) with A_c, from
    g(tf) = g_f (S4), the reference held at r(tf) after tf."""
    half, h = _grid(t0, tf, steps)
    f = _forcing(servo.C, servo.Q, reference, half)
    n = servo.A.shape[0]
    eye = np.eye(n)
    hM = h * servo.closed.T
    hM2 = _matmul(hM, hM)
    hM3 = _matmul(hM2, hM)
    T = eye + hM + hM2 / 2 + hM3 / 6 + _matmul(hM3, hM) / 24
    W0 = (eye + hM + hM2 / 2 + hM3 / 4) / 6
    Wm = (4 * eye + 2 * hM + hM2 / 2) / 6
    # the forcing of step k+1 -> k, for every k at once: rows h (W0 f_(k+1) + Wm f_(k+1/2) + W1 f_k)
    c = h * (_matmul(f[2::2], W0.T) + _matmul(f[1::2], Wm.T) + f[0:-1:2] / 6)
    g = np.zeros((steps + 1, n))
    g[steps] = servo.held_costate(np.ravel(reference(float(tf))))
    Tt = T.T
    for k in range(steps - 1, -1, -1):
        g[k] = _matmul(g[k + 1 : k + 2], Tt)[0] + c[k]
    return half[::2], g


def finite_horizon(A, B, C, Q, R, reference: Reference, t0: float, tf: float, steps: int, F=None) -> FiniteHorizonServo:
    """The time-varying servo of (S2, S3) on [t0, tf] with the terminal cost
    (y - r)^T F (y - r) at tf (F default zero): P(tf) = C^T F C, g(tf) = C^T F r(tf),
    integrated backwards together by RK4."""
    A, B, C, Q, R = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, Q, R))
    F = np.zeros((C.shape[0], C.shape[0])) if F is None else np.atleast_2d(np.asarray(F, float))
    half, h = _grid(t0, tf, steps)
    f = _forcing(C, Q, reference, half)
    Rinv_Bt = _solve(R, B.T)
    G = _matmul(B, Rinv_Bt)
    CtQC = _matmul(_matmul(C.T, Q), C)

    def rates(P: np.ndarray, g: np.ndarray, fk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # d/dtau of (S2, S3) in reversed time tau = tf - t
        AP = _matmul(A.T, P)
        dP = AP + AP.T - _matmul(P, _matmul(G, P)) + CtQC
        dg = _matmul((A - _matmul(G, P)).T, g[:, None])[:, 0] + fk
        return dP, dg

    n = A.shape[0]
    Ps = np.zeros((steps + 1, n, n))
    gs = np.zeros((steps + 1, n))
    CtF = _matmul(C.T, F)
    P, g = _matmul(CtF, C), _matmul(CtF, np.ravel(reference(float(tf)))[:, None])[:, 0]
    Ps[steps], gs[steps] = P, g
    for k in range(steps - 1, -1, -1):
        f0, fm, f1 = f[2 * k + 2], f[2 * k + 1], f[2 * k]
        k1 = rates(P, g, f0)
        k2 = rates(P + h / 2 * k1[0], g + h / 2 * k1[1], fm)
        k3 = rates(P + h / 2 * k2[0], g + h / 2 * k2[1], fm)
        k4 = rates(P + h * k3[0], g + h * k3[1], f1)
        P = P + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        g = g + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        P = 0.5 * (P + P.T)
        Ps[k], gs[k] = P, g
    K = np.array([_matmul(Rinv_Bt, P) for P in Ps])
    return FiniteHorizonServo(half[::2], Ps, gs, K, _matmul(gs, Rinv_Bt.T))
