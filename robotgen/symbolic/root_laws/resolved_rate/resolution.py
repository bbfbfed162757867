"""Joint rates from hand rates (Whitney 1972, eq 4) as CasADi SX, robust near singularities.

Never an explicit inverse: J is factorised by Householder QR, unrolled.

- Square arm: qdot = J^-1 Sdot (eq 4). Redundant arm (fewer task rows m than joints n): the
  minimum-norm qdot = J+ Sdot. Both come from one factorisation of A = [J^T; lambda I_m]
  ((n + m) x m) = Q [R; 0]: R^T R = J J^T + lambda^2 I, and the damped least-squares rate
  qdot = J^T (J J^T + lambda^2 I)^-1 Sdot = Q_top R^-T Sdot, Q_top the first n rows of Q's
  first m columns. With lambda = 0 this is J^-1 Sdot (square) or J+ Sdot (redundant).
- Weighted (redundant arm, W = diag(w) > 0): the rate of least qdot^T W qdot with J qdot =
  Sdot. Lagrange: W qdot = J^T mu, so qdot = W^-1 J^T (J W^-1 J^T)^-1 Sdot = J#W Sdot
  (Whitney 1969's weighted generalised inverse). With u = W^(1/2) qdot the cost is |u|^2 and
  the task J_w u = Sdot, J_w = J W^(-1/2): the minimum-norm u = J_w+ Sdot, so the same
  factorisation of the column-scaled J_w serves, qdot = W^(-1/2) u; damped, W^-1 J^T
  (J W^-1 J^T + lambda^2 I)^-1 Sdot.
- Singularities: manipulability w = sqrt(det(J J^T)) (Yoshikawa 1985) and the 2-norm
  condition number from the eigenvalues of J J^T (cyclic Jacobi, a fixed number of sweeps);
  lambda^2 = lambda_max^2 (1 - w / w0)^2 below the threshold w0 (Nakamura & Hanafusa 1986).
- Rate limits scale the whole vector, so the hand moves in the commanded direction, slower.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

CONDITION_CAP = 1e16  # the condition number reported at (numerically) singular configurations
JACOBI_SWEEPS = 6  # cyclic Jacobi on an m x m matrix (m <= 6 command axes): converged to rounding


def _entries(A: ca.SX) -> list[list[ca.SX]]:
    return [[A[i, j] for j in range(A.shape[1])] for i in range(A.shape[0])]


@dataclass(frozen=True, eq=False)
class Householder:
    """A = Q [R; 0] for a tall A (r x c, r >= c), Q = H_0 H_1 ... H_{c-1}, H_k = I - beta_k v_k v_k^T
    acting on rows k..r-1. Built without pivoting: A has full column rank where it is used."""

    rows: int
    R: list[list[ca.SX]]  # c x c upper triangle (entries below the diagonal are zero)
    v: list[list[ca.SX]]
    beta: list[ca.SX]

    @staticmethod
    def factor(A: ca.SX) -> Householder:
        """Householder QR of A (r x c, r >= c) as reflections and R."""
        r, c = A.shape
        assert r >= c, (r, c)
        a = _entries(A)
        vs, betas = [], []
        for k in range(c):
            x = [a[i][k] for i in range(k, r)]
            norm = ca.sqrt(sum((xi * xi for xi in x), ca.SX(0)))
            sign = ca.if_else(x[0] >= 0, 1, -1)
            v = [x[0] + sign * norm] + x[1:]
            vv = sum((vi * vi for vi in v), ca.SX(0))
            beta = ca.if_else(vv > 0, 2 / vv, 0)  # a zero column needs no reflection
            for j in range(k + 1, c):
                d = beta * sum((v[i] * a[k + i][j] for i in range(len(v))), ca.SX(0))
                for i in range(len(v)):
                    a[k + i][j] = a[k + i][j] - d * v[i]
            a[k][k] = -sign * norm
            for i in range(k + 1, r):
                a[i][k] = ca.SX(0)
            vs.append(v)
            betas.append(beta)
        return Householder(r, [row[:c] for row in a[:c]], vs, betas)

    @property
    def cols(self) -> int:
        """The number of columns of the factored matrix."""
        return len(self.R)

    def q_times(self, y: list[ca.SX]) -> list[ca.SX]:
        """Q y for y of length ``rows``."""
        y = list(y)
        for k in reversed(range(self.cols)):
            v, beta = self.v[k], self.beta[k]
            d = beta * sum((v[i] * y[k + i] for i in range(len(v))), ca.SX(0))
            for i in range(len(v)):
                y[k + i] = y[k + i] - d * v[i]
        return y

    def solve_rt(self, b: list[ca.SX]) -> list[ca.SX]:
        """R^-T b by forward substitution (R^T is lower triangular)."""
        R, c = self.R, self.cols
        z: list[ca.SX] = []
        for i in range(c):
            z.append((b[i] - sum((R[k][i] * z[k] for k in range(i)), ca.SX(0))) / R[i][i])
        return z


def symmetric_eigenvalues(G: ca.SX, sweeps: int = JACOBI_SWEEPS) -> list[ca.SX]:
    """Eigenvalues of a symmetric matrix by cyclic Jacobi rotations (unrolled, no pivoting
    choice): each rotation zeroes one off-diagonal entry, t = sgn(theta) / (|theta| +
    sqrt(theta^2 + 1)), theta = (a_qq - a_pp) / (2 a_pq), skipped when a_pq = 0."""
    m = G.shape[0]
    a = _entries(G)
    for _ in range(sweeps):
        for p in range(m - 1):
            for q in range(p + 1, m):
                apq = a[p][q]
                nonzero = apq != 0
                safe = ca.if_else(nonzero, apq, 1)
                theta = (a[q][q] - a[p][p]) / (2 * safe)
                t = ca.if_else(theta >= 0, 1, -1) / (ca.fabs(theta) + ca.sqrt(theta * theta + 1))
                t = ca.if_else(nonzero, t, 0)
                c = 1 / ca.sqrt(t * t + 1)
                s = t * c
                app, aqq = a[p][p] - t * apq, a[q][q] + t * apq
                for k in range(m):
                    if k in (p, q):
                        continue
                    akp, akq = a[k][p], a[k][q]
                    a[k][p] = a[p][k] = c * akp - s * akq
                    a[k][q] = a[q][k] = s * akp + c * akq
                a[p][p], a[q][q] = app, aqq
                a[p][q] = a[q][p] = ca.SX(0)
    return [a[i][i] for i in range(m)]


@dataclass(frozen=True, eq=False)
class Conditioning:
    """Conditioning of J: the manipulability w = sqrt(det(J J^T)) and the capped condition number."""

    manipulability: ca.SX  # w = sqrt(det(J J^T)) = product of singular values
    condition: ca.SX  # sigma_max / sigma_min, capped at CONDITION_CAP


def conditioning(J: ca.SX) -> Conditioning:
    """Conditioning of a task Jacobian J (m, n) from the eigenvalues of J J^T."""
    mu = [ca.fmax(e, 0) for e in symmetric_eigenvalues(J @ J.T)]
    w = ca.sqrt(_product(mu))
    big = _reduce(ca.fmax, mu)
    small = _reduce(ca.fmin, mu)
    cond = ca.sqrt(big / ca.fmax(small, big / CONDITION_CAP**2))
    cond = ca.if_else(big > 0, cond, CONDITION_CAP)
    return Conditioning(w, cond)


def _product(values: list[ca.SX]) -> ca.SX:
    out = ca.SX(1)
    for v in values:
        out = out * v
    return out


def _reduce(op, values: list[ca.SX]) -> ca.SX:
    out = values[0]
    for v in values[1:]:
        out = op(out, v)
    return out


def damping_squared(w: ca.SX, lambda_max: float, threshold: float) -> ca.SX:
    """lambda^2 = lambda_max^2 (1 - w / w0)^2 for w < w0, else 0 (Nakamura & Hanafusa 1986)."""
    return ca.if_else(w < threshold, lambda_max**2 * (1 - w / threshold) ** 2, 0)


class DampedResolver:
    """One factorisation of [J^T; lambda I] serving the task rates and the null-space
    projection: J+_lambda b = Q_top R^-T b, (I - J+_lambda J) z = z - J+_lambda (J z).

    With ``column_scale`` s = W^(-1/2) (the diagonal, constants) J_w = J diag(s) is factorised
    instead and pinv_times is the weighted J#W b = s * J_w+ b. project_null is then
    z - J#W J z = W^(-1/2) (I - J_w+ J_w) W^(1/2) z: the projection onto null(J) orthogonal in
    the metric W; applied to W^-1 grad H (the steepest ascent of H in that metric) it is
    W^(-1/2) (I - J_w+ J_w) W^(-1/2) grad H, the Liegeois term in u = W^(1/2) qdot."""

    def __init__(self, J: ca.SX, lam2: ca.SX | None, column_scale: np.ndarray | None = None):
        self.J = J
        m, n = J.shape
        self.n = n
        self.scale = None if column_scale is None else ca.DM(column_scale)
        Jw = J if self.scale is None else J @ ca.diag(self.scale)
        lower = ca.sqrt(lam2) * ca.SX.eye(m) if lam2 is not None else ca.SX.zeros(m, m)
        self.qr = Householder.factor(ca.vertcat(Jw.T, lower) if lam2 is not None else Jw.T)

    def pinv_times(self, b: ca.SX) -> ca.SX:
        """J+_lambda b (weighted when columns are scaled) for a task-rate vector b (m,)."""
        z = self.qr.solve_rt([b[i] for i in range(b.shape[0])])
        y = self.qr.q_times(z + [ca.SX(0)] * (self.qr.rows - len(z)))
        u = ca.vertcat(*y[: self.n])
        return u if self.scale is None else self.scale * u

    def project_null(self, z: ca.SX) -> ca.SX:
        """(I - J+_lambda J) z: z (n,) projected onto the null space of J."""
        return z - self.pinv_times(self.J @ z)


def limit_divisor(qd: ca.SX, limits) -> ca.SX | None:
    """max(1, max_i |qd_i| / limit_i), or None without limits."""
    if limits is None:
        return None
    ratio = _reduce(ca.fmax, [ca.fabs(qd[i]) / float(limits[i]) for i in range(qd.shape[0])])
    return ca.fmax(1, ratio)


def scale_to_limits(qd: ca.SX, limits) -> ca.SX:
    """qd / max(1, max_i |qd_i| / limit_i): the direction (and so the hand's) is kept."""
    divisor = limit_divisor(qd, limits)
    return qd if divisor is None else qd / divisor


def limited(qd: ca.SX, limits) -> tuple[ca.SX, ca.SX]:
    """(qd scaled to the limits, the factor 1 / max(1, max_i |qd_i| / limit_i) it was scaled by)."""
    divisor = limit_divisor(qd, limits)
    return (qd, ca.SX(1)) if divisor is None else (qd / divisor, 1 / divisor)


def null_vector(J: ca.SX) -> ca.SX:
    """Unit vector spanning null(J) for J of m rows, m + 1 columns: the last column of Q in
    J^T = Q [R; 0] (its sign may flip; what uses it must not care)."""
    m, n = J.shape
    assert n == m + 1
    qr = Householder.factor(J.T)
    e = [ca.SX(0)] * n
    e[n - 1] = ca.SX(1)
    return ca.vertcat(*qr.q_times(e))
