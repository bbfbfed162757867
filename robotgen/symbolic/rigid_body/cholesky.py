"""Solve M x = b for symmetric positive definite M by an unrolled factorisation
M = L D L^T (L unit lower triangular, D diagonal, no square roots), then two triangular
solves. M^-1 is formed only where it is a result itself (forward dynamics' derivatives), and
there it also multiplies their other columns (schedule_inverse_product). The reciprocals of
D are formed once, in the factorisation: every solve multiplies by them (a division costs
several multiplications, and a matrix of right-hand sides would repeat them). Without square
roots the factorisation's chain of dependent operations per column is a division shorter
than Cholesky's. A pivot d_j <= 0 (M not positive definite) makes every d and 1 / d NaN,
which reaches every result, so the checked functions return their status
(robotgen.symbolic.kernel.Kernel.guarded) as a square root of a negative number would make
them."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.symbolic.schedule import LOCAL, RANGE, ScheduleBuilder, Slice, body


@dataclass(frozen=True, eq=False)
class Cholesky:
    """M = L D L^T (no square roots): L unit lower triangular, d and 1/d, as lists of SX."""

    L: list[list[ca.SX]]  # unit lower triangular (the diagonal is 1 and not read), M = L D L^T
    diagonal: list[ca.SX]  # d_i (every one NaN when M is not positive definite)
    inverse_diagonal: list[ca.SX]  # 1 / d_i (likewise)


def cholesky_factor(M: ca.SX) -> Cholesky:
    """The pivots' chain of dependent operations is kept short: d_j = M_jj - sum_k E_jk^2 / d_k
    (E_jk^2 is ready before 1 / d_k, and the last pivot's term is subtracted last), and the
    test d_j > 0 is off the chain: one term, NaN unless every pivot is positive, is added to
    d and 1 / d once they are all known."""
    n = M.shape[0]
    L = [[ca.SX(0)] * n for _ in range(n)]
    E = [[ca.SX(0)] * n for _ in range(n)]  # E_ij = L_ij d_j
    pivots, inverse = [ca.SX(0)] * n, [ca.SX(0)] * n
    for j in range(n):
        pivots[j] = _minus_terms(M[j, j], [(E[j][k] * E[j][k]) * inverse[k] for k in range(j)])
        inverse[j] = 1 / pivots[j]
        for i in range(j + 1, n):
            E[i][j] = _minus_terms(M[i, j], [E[i][k] * L[j][k] for k in range(j)])
            L[i][j] = E[i][j] * inverse[j]
    positive = pivots[0] > 0
    for pivot in pivots[1:]:
        positive = ca.logic_and(positive, pivot > 0)
    nan_unless_positive = ca.if_else(positive, ca.SX(0), ca.SX(float("nan")))
    return Cholesky(L, [p + nan_unless_positive for p in pivots], [v + nan_unless_positive for v in inverse])


def cholesky_substitute(factor: Cholesky, b: ca.SX) -> ca.SX:
    """x with L D L^T x = b (b a column): forward substitution, scaling, back substitution."""
    L, inverse = factor.L, factor.inverse_diagonal
    n = len(L)
    y = [ca.SX(0)] * n
    for i in range(n):
        y[i] = _minus_terms(b[i], [L[i][k] * y[k] for k in range(i)])
    x = [ca.SX(0)] * n
    for i in reversed(range(n)):
        x[i] = _minus_terms(y[i] * inverse[i], [L[k][i] * x[k] for k in reversed(range(i + 1, n))])
    return ca.vertcat(*x)


def _minus_terms(value: ca.SX, terms: list[ca.SX]) -> ca.SX:
    """value - t_1 - t_2 - ..., in this order: the term known last (the latest pivot's, the
    latest unknown's) is listed last, one subtraction before the result."""
    for term in terms:
        value = value - term
    return value


def cholesky_solve(M: ca.SX, b: ca.SX) -> ca.SX:
    """M^-1 b for a symmetric positive definite M (n, n) and b (n,) or (n, k), by L D L^T."""
    return cholesky_substitute(cholesky_factor(M), b)


def cholesky_substitute_columns(factor: Cholesky, B: ca.SX) -> ca.SX:
    """M^-1 B for a factorisation of M already made."""
    return ca.horzcat(*[cholesky_substitute(factor, B[:, k]) for k in range(B.shape[1])])


def cholesky_solve_matrix(M: ca.SX, B: ca.SX) -> ca.SX:
    """M^-1 B, one factorisation for every column of B."""
    return cholesky_substitute_columns(cholesky_factor(M), B)


def cholesky_inverse(M: ca.SX) -> ca.SX:
    """M^-1 for a symmetric positive definite M, as L^-T D^-1 L^-1: W = L^-1 column by column
    (each column's forward substitution on a unit vector), then (M^-1)_ij = sum_k W_ki W_kj / d_k
    over k >= max(i, j) for i <= j only, mirrored. Half the back substitutions' work, and each
    entry a sum of independent products where a back substitution waits row by row."""
    factor = cholesky_factor(M)
    L, inverse = factor.L, factor.inverse_diagonal
    n = len(L)
    W = [[ca.SX(0)] * n for _ in range(n)]  # W[i][c], unit lower triangular
    for c in range(n):
        W[c][c] = ca.SX(1)
        for i in range(c + 1, n):
            W[i][c] = _minus_terms(-L[i][c], [L[i][k] * W[k][c] for k in range(c + 1, i)])
    X = ca.SX.zeros(n, n)
    for i in range(n):
        for j in range(i, n):
            terms = [(W[k][i] * inverse[k]) * W[k][j] for k in range(j, n)]
            total = terms[0]
            for term in terms[1:]:
                total = total + term
            X[i, j] = total
            X[j, i] = total
    return X


def solve_coefficients(factor: Cholesky) -> ca.SX:
    """The factorisation as one column, for a loop body to read (solve_with_coefficients): F
    (n x n, row-major) with F_ij = L_ij below the diagonal, B with B_ik = d_i L_ki / d_k above
    it, and 1 / d_i. With them M x = r is solved by a forward pass, for i = 1, ..., n-1,
    r_i -= F_ij r_j (j < i), a back pass, for i = n-2, ..., 0, r_i -= B_ik r_k (k > i), and
    x_i = r_i / d_i. (The forward pass leaves r = L^-1 r; the back pass r_i = d_i x_i.)"""
    L, d, inverse = factor.L, factor.diagonal, factor.inverse_diagonal
    n = len(L)
    F = ca.SX.zeros(n, n)
    B = ca.SX.zeros(n, n)
    for i in range(n):
        for j in range(i):
            F[i, j] = L[i][j]
            B[j, i] = d[j] * L[i][j] * inverse[i]
    return ca.vertcat(ca.vec(F.T), ca.vec(B.T), ca.vertcat(*inverse))


def solve_with_coefficients(coefficients: ca.SX, rhs: ca.SX) -> ca.SX:
    """M^-1 rhs from solve_coefficients (a column of n (2 n + 1) values) by the same
    forward and back passes, for one right-hand side."""
    n = rhs.shape[0]
    F = ca.reshape(coefficients[: n * n], n, n).T
    B = ca.reshape(coefficients[n * n : 2 * n * n], n, n).T
    r = [rhs[i] for i in range(n)]
    for j in range(n):
        for i in range(j + 1, n):
            r[i] = r[i] - F[i, j] * r[j]
    for k in reversed(range(1, n)):
        for i in range(k):
            r[i] = r[i] - B[i, k] * r[k]
    return ca.vertcat(*(coefficients[2 * n * n + i] * r[i] for i in range(n)))


def schedule_inverse_product(
    b: ScheduleBuilder, n: int, inverse: int, rows: int, width: int, blocks: list[tuple[tuple[str, int], int, float]]
) -> None:
    """M^-1 R for the local ``rows`` (n x width, row-major) with M^-1 already formed (the local
    ``inverse``, n x n row-major): row i of the result is sum_k (M^-1)_ik R_k, one loop step
    per row. The rows are independent, so the processor overlaps them, where a row-wise solve
    waits at every row for the rows before it (docs/performance-log.md). Each block (target, first
    column, scale) writes scale times columns first..first+n-1 of the product to an n x n
    row-major array."""
    m, R = ca.SX.sym("m", n), ca.SX.sym("R", n * width)
    y = sum((m[k] * R[k * width : (k + 1) * width] for k in range(1, n)), m[0] * R[:width])
    b.loop(
        body("inverse_rows", [m, R], [scale * y[first : first + n] for _, first, scale in blocks]),
        RANGE,
        n,
        [Slice(LOCAL, inverse, i_stride=n), Slice(LOCAL, rows)],
        [Slice(*target, i_stride=n) for target, _, _ in blocks],
    )
