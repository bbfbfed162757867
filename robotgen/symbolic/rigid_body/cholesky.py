"""Solve M x = b for symmetric positive definite M by an unrolled Cholesky factorisation
(M = L L^T, then two triangular solves); never an explicit inverse."""
from __future__ import annotations

import casadi as ca


def cholesky_factor(M: ca.SX) -> list[list[ca.SX]]:
    """L, lower triangular, with M = L L^T."""
    n = M.shape[0]
    L = [[ca.SX(0)] * n for _ in range(n)]
    for j in range(n):
        s = M[j, j] - sum((L[j][k] * L[j][k] for k in range(j)), ca.SX(0))
        L[j][j] = ca.sqrt(s)
        inv = 1 / L[j][j]
        for i in range(j + 1, n):
            s = M[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), ca.SX(0))
            L[i][j] = s * inv
    return L


def cholesky_substitute(L: list[list[ca.SX]], b: ca.SX) -> ca.SX:
    """x with L L^T x = b (b a column): forward, then back substitution."""
    n = len(L)
    y = [ca.SX(0)] * n
    for i in range(n):
        y[i] = (b[i] - sum((L[i][k] * y[k] for k in range(i)), ca.SX(0))) / L[i][i]
    x = [ca.SX(0)] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), ca.SX(0))) / L[i][i]
    return ca.vertcat(*x)


def cholesky_solve(M: ca.SX, b: ca.SX) -> ca.SX:
    return cholesky_substitute(cholesky_factor(M), b)


def cholesky_solve_matrix(M: ca.SX, B: ca.SX) -> ca.SX:
    """M^-1 B, one factorisation for every column of B."""
    L = cholesky_factor(M)
    return ca.horzcat(*[cholesky_substitute(L, B[:, k]) for k in range(B.shape[1])])
