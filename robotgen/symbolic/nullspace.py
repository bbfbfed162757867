"""Orthonormal bases of null spaces as smooth symbolic expressions: K spanning null(J)
(internal motions, Deno et al. 1990 eq 2.5) and H spanning null(G) (internal forces,
eq 2.4). An SVD has no symbolic form, so:
- co-dimension one (an (m-1) x m full-rank matrix): the generalised cross product, whose
  entries are the signed (m-1)-minors, normalised;
- larger: Gram-Schmidt on the projector I - A^+ A applied to k fixed directions drawn once
  from a seeded generator, the same on every machine (coordinate axes would often lie in
  the row space of a sparse A, leaving 0/0); smooth wherever those projections stay
  independent, which for generic directions is everywhere but a set of measure zero.
Blocks of a block-diagonal matrix are handled one block at a time, so two redundant
fingers give two orthonormal rows with disjoint support."""

from __future__ import annotations

import random

import casadi as ca


def _det(A: ca.SX) -> ca.SX:
    return ca.det(A)


def generalized_cross(A: ca.SX) -> ca.SX:
    """Row vector orthogonal to the m-1 rows of A (m columns), unnormalised."""
    m = A.shape[1]
    cols = list(range(m))
    return ca.horzcat(*[(-1) ** j * _det(A[:, [c for c in cols if c != j]]) for j in range(m)])


def null_rows(A: ca.SX) -> ca.SX:
    """Rows forming an orthonormal basis of null(A) for a full-row-rank A (r x m)."""
    r, m = A.shape
    k = m - r
    if k == 0:
        return ca.SX(0, m)
    if k == 1:
        v = generalized_cross(A)
        return v / ca.norm_2(v.T)
    P = ca.SX.eye(m) - A.T @ ca.solve(A @ A.T, A)
    generator = random.Random(20260101)  # Mersenne Twister: the same directions on every machine
    directions = [[generator.uniform(-1.0, 1.0) for _ in range(m)] for _ in range(k)]
    return gram_schmidt([P @ ca.DM(d) for d in directions])


def gram_schmidt(vectors: list[ca.SX]) -> ca.SX:
    """Orthonormal rows spanning the given independent column vectors, in order."""
    rows: list[ca.SX] = []
    for v in vectors:
        for u in rows:
            v = v - (u @ v) * u.T
        rows.append((v / ca.norm_2(v)).T)
    return ca.vertcat(*rows)


def block_null_rows(A: ca.SX, row_blocks: list[int], col_blocks: list[int]) -> ca.SX:
    """null_rows of a block-diagonal A, block by block, embedded in the full column space."""
    m = A.shape[1]
    out = []
    r0 = c0 = 0
    for nr, nc in zip(row_blocks, col_blocks):
        K = null_rows(A[r0 : r0 + nr, c0 : c0 + nc])
        if K.shape[0]:
            out.append(ca.horzcat(ca.SX(K.shape[0], c0), K, ca.SX(K.shape[0], m - c0 - nc)))
        r0, c0 = r0 + nr, c0 + nc
    return ca.vertcat(*out) if out else ca.SX(0, m)
