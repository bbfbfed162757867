"""4x4 homogeneous transforms with numpy (constant geometry: DH rows, origins, tools)."""
from __future__ import annotations

import numpy as np

from robotgen.model.chain import PRISMATIC


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]], dtype=float)


def rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]], dtype=float)


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)


def trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def xyz_rpy(xyz, rpy) -> np.ndarray:
    """URDF origin: translation xyz, then fixed-axis roll-pitch-yaw,
    R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw = rpy
    return trans(*xyz) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def axis_rotation(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)
    return T


def joint_motion(joint_type: str, axis, q: float) -> np.ndarray:
    """The joint's motion at q: rotation about ``axis`` (revolute) or translation along it
    (prismatic), as in robotgen.model.chain."""
    if joint_type == PRISMATIC:
        return trans(*(np.asarray(axis, dtype=float) * q))
    return axis_rotation(axis, q)
