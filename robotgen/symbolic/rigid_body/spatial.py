"""Small 3-D helpers on CasADi SX: rotations, cross products, rigid motions.

Spatial vectors follow Featherstone's (angular; linear) ordering, but are kept as pairs of
3-vectors so that CasADi sees only the products that are not structurally zero.
"""

from __future__ import annotations

import casadi as ca
import numpy as np


def const(a: np.ndarray) -> ca.SX:
    """A numpy array as a constant SX."""
    return ca.SX(ca.DM(np.asarray(a, dtype=float)))


def skew(v: ca.SX) -> ca.SX:
    """[v x] (3, 3): the skew-symmetric matrix with [v x] w = v x w."""
    return ca.vertcat(
        ca.horzcat(0, -v[2], v[1]),
        ca.horzcat(v[2], 0, -v[0]),
        ca.horzcat(-v[1], v[0], 0),
    )


def axis_rotation(axis: np.ndarray, c: ca.SX, s: ca.SX) -> ca.SX:
    """Rotation by an angle with cosine c and sine s about a constant unit axis k (Rodrigues):
    R = c I + s K + (1 - c) k k^T, K = skew(k). Entries that are zero stay structural zeros,
    and about a coordinate axis the others are exactly c, +-s and 1 (not 1 - (1 - c))."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    kk = np.outer(k, k)
    R = ca.SX(3, 3)
    for i in range(3):
        for j in range(3):
            if i == j:
                R[i, j] = 1.0 if kk[i, i] == 1.0 else c if kk[i, i] == 0.0 else c + (1 - c) * kk[i, i]
            elif K[i, j] or kk[i, j]:
                R[i, j] = (s * K[i, j] if K[i, j] else 0) + ((1 - c) * kk[i, j] if kk[i, j] else 0)
    return R


def rotate_symmetric(R: ca.SX, X: ca.SX) -> ca.SX:
    """R X R^T for a symmetric X: (R X) R^T formed on its upper triangle only."""
    RX = R @ X
    Y = ca.SX.zeros(3, 3)
    for i in range(3):
        for j in range(i, 3):
            Y[i, j] = Y[j, i] = ca.dot(RX[i, :].T, R[j, :].T)
    return Y


def homogeneous(R: ca.SX, p: ca.SX) -> ca.SX:
    """(4, 4) homogeneous transform of rotation R (3, 3) and translation p (3,)."""
    return ca.vertcat(ca.horzcat(R, p), ca.horzcat(ca.SX.zeros(1, 3), ca.SX.ones(1, 1)))


def motion_transform(m, w: ca.SX, v: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Apply X = [E 0; -E skew(r) E] of joint motion ``m`` (a kinematics.JointMotion) to the
    motion (w, v) given in the parent frame; E maps parent to child coordinates and r is
    the child origin in parent coordinates."""
    return m.to_child(w), m.to_child(v - ca.cross(m.r, w))


def force_transform_to_parent(m, n: ca.SX, f: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Apply X^T of joint motion ``m`` to the force (n, f) given in the child frame."""
    fp = m.to_parent(f)
    return m.to_parent(n) + ca.cross(m.r, fp), fp


def motion_cross(w: ca.SX, v: ca.SX, mw: ca.SX, mv: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(w, v) x (mw, mv) for motion vectors."""
    return ca.cross(w, mw), ca.cross(w, mv) + ca.cross(v, mw)


def force_cross(w: ca.SX, v: ca.SX, n: ca.SX, f: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(w, v) x* (n, f) for a force vector."""
    return ca.cross(w, n) + ca.cross(v, f), ca.cross(w, f)


def motion_cross6(a: ca.SX, b: ca.SX) -> ca.SX:
    """motion_cross on stacked 6-vectors (angular; linear)."""
    return ca.vertcat(*motion_cross(a[:3], a[3:], b[:3], b[3:]))


def force_cross6(a: ca.SX, f: ca.SX) -> ca.SX:
    """force_cross on stacked 6-vectors."""
    return ca.vertcat(*force_cross(a[:3], a[3:], f[:3], f[3:]))
