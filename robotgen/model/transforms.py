"""4x4 homogeneous transforms of constant geometry (DH rows, origins, tools), computed with
robotgen.numeric.exact so that every entry is the same on every machine."""

from __future__ import annotations

import numpy as np

from robotgen.numeric import exact


def _rotation(c: float, s: float, axis: int) -> np.ndarray:
    """Rotation by the angle with cosine c and sine s about base axis 0 (x), 1 (y) or 2 (z)."""
    i, k = [(1, 2), (2, 0), (0, 1)][axis]
    T = np.eye(4)
    T[i, i], T[i, k], T[k, i], T[k, k] = c, -s, s, c
    return T


def rot_x(angle: float) -> np.ndarray:
    """(4, 4) homogeneous rotation about x by ``angle`` [rad] (sin and cos correctly rounded)."""
    return _rotation(*exact.sin_cos(angle)[::-1], 0)


def rot_y(angle: float) -> np.ndarray:
    """(4, 4) homogeneous rotation about y by ``angle`` [rad] (sin and cos correctly rounded)."""
    return _rotation(*exact.sin_cos(angle)[::-1], 1)


def rot_z(angle: float) -> np.ndarray:
    """(4, 4) homogeneous rotation about z by ``angle`` [rad] (sin and cos correctly rounded)."""
    return _rotation(*exact.sin_cos(angle)[::-1], 2)


def trans(x: float, y: float, z: float) -> np.ndarray:
    """(4, 4) homogeneous translation by (x, y, z) [m]."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def xyz_rpy(xyz, rpy) -> np.ndarray:
    """URDF origin: translation xyz, then fixed-axis roll-pitch-yaw,
    R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw = rpy
    return exact.matmul(trans(*xyz), rot_z(yaw), rot_y(pitch), rot_x(roll))
