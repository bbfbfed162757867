"""Solve M x = b for symmetric positive definite M by an unrolled Cholesky factorisation
(M = L L^T, then two triangular solves); never an explicit inverse. The reciprocals of L's
diagonal are formed once, in the factorisation: every solve multiplies by them (a division
costs several multiplications, and a matrix of right-hand sides would repeat them)."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


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
