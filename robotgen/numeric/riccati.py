"""The continuous algebraic Riccati equation A^T P + P A - P B R^-1 B^T P + Q = 0, solved so
that the gains robotgen prints into C are the same on every machine.

LAPACK's Schur-based solvers (scipy's solve_continuous_are) run on the BLAS kernel the CPU
selects, and their result differs between kernels far beyond the last bit when the problem
is stiff (a PUMA 560 regulator's gains differed in the 8th digit). Here every operation is an
elementwise numpy operation or a Python float operation in a fixed order: no BLAS, no LAPACK,
no libm. Products are accumulated column by column (``_matmul``), systems are solved by
Gauss-Jordan elimination with partial pivoting.

Method (Roberts 1980; Byers 1987; Kleinman 1968):
1. the matrix sign function of the Hamiltonian H = [A, -G; -Q, -A^T], G = B R^-1 B^T, by the
   scaled Newton iteration Z <- (Z / c + c Z^-1) / 2, c = sqrt(|Z^-1|_F / |Z|_F);
2. P from sign(H) = W: [W12; W22 + I] P = -[W11 + I; W21], in the least-squares sense;
3. Newton-Kleinman steps: K = R^-1 B^T P, then P solves the Lyapunov equation
   (A - B K)^T P + P (A - B K) + Q + K^T R K = 0 (over the n(n+1)/2 entries of a symmetric
   P), which restores full accuracy.
"""

from __future__ import annotations

import math

import numpy as np

SIGN_TOLERANCE = 1e-13
MAX_SIGN_STEPS = 100
KLEINMAN_STEPS = 3


class RiccatiError(ValueError):
    """No stabilising solution: (A, B) not stabilisable or (A, Q) has unobservable modes on
    the imaginary axis."""


def _matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A @ B by a fixed sequence of elementwise products and sums (no BLAS)."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    out = np.zeros((A.shape[0], B.shape[1]))
    for k in range(A.shape[1]):
        out = out + A[:, k : k + 1] * B[k : k + 1, :]
    return out


def _solve(M: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """M X = rhs by Gauss-Jordan elimination with partial pivoting."""
    n = M.shape[0]
    a = np.hstack([np.array(M, float), np.array(rhs, float).reshape(n, -1)])
    for k in range(n):
        p = k + int(np.argmax(np.abs(a[k:, k])))
        if a[p, k] == 0.0:
            raise RiccatiError("singular matrix in the Riccati solver")
        if p != k:
            a[[k, p]] = a[[p, k]]
        a[k] = a[k] / a[k, k]
        factors = a[:, k : k + 1].copy()
        factors[k] = 0.0
        a = a - factors * a[k : k + 1, :]
    return a[:, n:]


def _frobenius(A: np.ndarray) -> float:
    total = 0.0
    for v in np.asarray(A, float).ravel().tolist():
        total += v * v
    return math.sqrt(total)


def _sign(H: np.ndarray) -> np.ndarray:
    Z = np.array(H, float)
    eye = np.eye(Z.shape[0])
    for _ in range(MAX_SIGN_STEPS):
        Zi = _solve(Z, eye)
        c = math.sqrt(_frobenius(Zi) / _frobenius(Z))
        Z_next = 0.5 * (c * Z + Zi / c)
        change = _frobenius(Z_next - Z)
        Z = Z_next
        if change <= SIGN_TOLERANCE * _frobenius(Z):
            return Z
    raise RiccatiError(
        "the sign iteration did not converge (eigenvalues of the Hamiltonian on or near the imaginary axis)"
    )


def _lyapunov(Ac: np.ndarray, S: np.ndarray) -> np.ndarray:
    """The symmetric X with Ac^T X + X Ac + S = 0, over the entries X_ij, i <= j."""
    n = Ac.shape[0]
    pairs = [(i, j) for i in range(n) for j in range(i, n)]
    index = {p: k for k, p in enumerate(pairs)}
    L = np.zeros((len(pairs), len(pairs)))
    for row, (i, j) in enumerate(pairs):
        # (Ac^T X + X Ac)_ij = sum_k Ac_ki X_kj + X_ik Ac_kj
        for k in range(n):
            L[row, index[(min(k, j), max(k, j))]] += Ac[k, i]
            L[row, index[(min(i, k), max(i, k))]] += Ac[k, j]
    x = _solve(L, -np.array([S[i, j] for i, j in pairs]))[:, 0]
    X = np.zeros((n, n))
    for (i, j), v in zip(pairs, x.tolist()):
        X[i, j] = X[j, i] = v
    return X


def solve_care(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The stabilising solution P (symmetric, A - B R^-1 B^T P Hurwitz)."""
    A, B, Q, R = (np.asarray(x, float) for x in (A, B, Q, R))
    n = A.shape[0]
    Rinv_Bt = _solve(R, B.T)
    G = _matmul(B, Rinv_Bt)
    H = np.block([[A, -G], [-Q, -A.T]])
    W = _sign(H)
    eye = np.eye(n)
    M = np.vstack([W[:n, n:], W[n:, n:] + eye])
    N = -np.vstack([W[:n, :n] + eye, W[n:, :n]])
    P = _solve(_matmul(M.T, M), _matmul(M.T, N))
    P = 0.5 * (P + P.T)
    for _ in range(KLEINMAN_STEPS):
        K = _matmul(Rinv_Bt, P)
        Ac = A - _matmul(B, K)
        P = _lyapunov(Ac, Q + _matmul(K.T, _matmul(R, K)))
    return P


def gain(B: np.ndarray, R: np.ndarray, P: np.ndarray) -> np.ndarray:
    """K = R^-1 B^T P."""
    return _matmul(_solve(R, np.asarray(B, float).T), P)
