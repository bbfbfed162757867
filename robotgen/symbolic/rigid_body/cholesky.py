"""Solve M x = b for symmetric positive definite M by an unrolled Cholesky factorisation
(M = L L^T, then two triangular solves); never an explicit inverse. The reciprocals of L's
diagonal are formed once, in the factorisation: every solve multiplies by them (a division
costs several multiplications, and a matrix of right-hand sides would repeat them)."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.symbolic.schedule import LOCAL, RANGE, ROWS_ABOVE_DESCENDING, ROWS_BELOW, ScheduleBuilder, Slice, body


@dataclass(frozen=True, eq=False)
class Cholesky:
    L: list[list[ca.SX]]  # lower triangular, M = L L^T
    inverse_diagonal: list[ca.SX]  # 1 / L[i][i]


def cholesky_factor(M: ca.SX) -> Cholesky:
    n = M.shape[0]
    L = [[ca.SX(0)] * n for _ in range(n)]
    inverse = [ca.SX(0)] * n
    for j in range(n):
        s = M[j, j] - sum((L[j][k] * L[j][k] for k in range(j)), ca.SX(0))
        L[j][j] = ca.sqrt(s)
        inverse[j] = 1 / L[j][j]
        for i in range(j + 1, n):
            s = M[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), ca.SX(0))
            L[i][j] = s * inverse[j]
    return Cholesky(L, inverse)


def cholesky_substitute(factor: Cholesky, b: ca.SX) -> ca.SX:
    """x with L L^T x = b (b a column): forward, then back substitution."""
    L, inverse = factor.L, factor.inverse_diagonal
    n = len(L)
    y = [ca.SX(0)] * n
    for i in range(n):
        y[i] = (b[i] - sum((L[i][k] * y[k] for k in range(i)), ca.SX(0))) * inverse[i]
    x = [ca.SX(0)] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), ca.SX(0))) * inverse[i]
    return ca.vertcat(*x)


def cholesky_solve(M: ca.SX, b: ca.SX) -> ca.SX:
    return cholesky_substitute(cholesky_factor(M), b)


def cholesky_substitute_columns(factor: Cholesky, B: ca.SX) -> ca.SX:
    """M^-1 B for a factorisation of M already made."""
    return ca.horzcat(*[cholesky_substitute(factor, B[:, k]) for k in range(B.shape[1])])


def cholesky_solve_matrix(M: ca.SX, B: ca.SX) -> ca.SX:
    """M^-1 B, one factorisation for every column of B."""
    return cholesky_substitute_columns(cholesky_factor(M), B)


def row_solve_coefficients(factor: Cholesky) -> ca.SX:
    """What schedule_row_solve reads, as one column: F (n x n, row-major) with
    F_ij = L_ij / L_jj below the diagonal, B with B_ik = L_ki L_ii / L_kk^2 above it, and
    d_i = 1 / L_ii^2.

    With them, M X = R for a matrix of right-hand sides R is solved row by row, every update a
    whole row at once (the columns are independent, so the processor overlaps them; solving
    column after column is a chain of dependent operations per column): forward, for
    i = 1, ..., n-1, R_i -= F_ij R_j (j < i); back, for i = n-2, ..., 0, R_i -= B_ik R_k (k > i);
    then X_i = d_i R_i. (The forward pass leaves R_i = L_ii y_i with L y = R; the back pass
    R_i = L_ii^2 x_i.)"""
    L, inverse = factor.L, factor.inverse_diagonal
    n = len(L)
    F = ca.SX.zeros(n, n)
    B = ca.SX.zeros(n, n)
    for i in range(n):
        for j in range(i):
            F[i, j] = L[i][j] * inverse[j]
            B[j, i] = L[i][j] * L[j][j] * inverse[i] * inverse[i]
    d = ca.vertcat(*(inverse[i] * inverse[i] for i in range(n)))
    return ca.vertcat(ca.vec(F.T), ca.vec(B.T), d)


def solve_with_coefficients(coefficients: ca.SX, rhs: ca.SX) -> ca.SX:
    """M^-1 rhs from row_solve_coefficients (a column of n (2 n + 1) values) by the same
    forward and back passes, for one right-hand side."""
    n = rhs.shape[0]
    F = ca.reshape(coefficients[:n * n], n, n).T
    B = ca.reshape(coefficients[n * n:2 * n * n], n, n).T
    r = [rhs[i] for i in range(n)]
    for j in range(n):
        for i in range(j + 1, n):
            r[i] = r[i] - F[i, j] * r[j]
    for k in reversed(range(1, n)):
        for i in range(k):
            r[i] = r[i] - B[i, k] * r[k]
    return ca.vertcat(*(coefficients[2 * n * n + i] * r[i] for i in range(n)))


def schedule_row_solve(b: ScheduleBuilder, n: int, coefficients: int, rows: int, width: int,
                       blocks: list[tuple[tuple[str, int], int, float]]) -> None:
    """M^-1 R for the local ``rows`` (n x width, row-major; overwritten), with ``coefficients``
    a local holding row_solve_coefficients; each block (target, first column, scale) writes
    scale times columns first..first+n-1 of the solution to an n x n row-major array."""
    r_i, r_j, c, d = ca.SX.sym("r_i", width), ca.SX.sym("r_j", width), ca.SX.sym("c"), ca.SX.sym("d")
    update = body("row_update", [r_i, c, r_j], [r_i - c * r_j])
    row = Slice(LOCAL, rows, i_stride=width)
    b.loop(update, ROWS_BELOW, n, [row, Slice(LOCAL, coefficients, i_stride=n, j_stride=1),
                              Slice(LOCAL, rows, j_stride=width)], [row])
    b.loop(update, ROWS_ABOVE_DESCENDING, n, [row, Slice(LOCAL, coefficients, n * n, i_stride=n, j_stride=1),
                                         Slice(LOCAL, rows, j_stride=width)], [row])
    scaled = body("row_scale", [r_i, d], [scale * d * r_i[first:first + n] for _, first, scale in blocks])
    b.loop(scaled, RANGE, n, [row, Slice(LOCAL, coefficients, 2 * n * n, i_stride=1)],
           [Slice(*target, i_stride=n) for target, _, _ in blocks])
