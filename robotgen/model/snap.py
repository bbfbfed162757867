"""Snap the constants of a kinematic tree that are exact in intent but not in floating point.

A URDF's rpy of 1.5707963 (or a DH alpha of pi/2) gives rotation entries like 4.9e-12 or
6.1e-17 where the designer meant 0, and 1 - 1e-12 where they meant 1. Left as they are,
every such entry multiplies through the symbolic algorithms as a non-zero and the emitted C
carries their products. Entries of joint and tool rotations and of joint axes within
SNAP_TOLERANCE of 0 or +-1 are snapped, and only when the snapped rotation is still
orthonormal to 1e-15 (so nothing but noise is ever removed). The snapped model differs
from the unsnapped one by at most the tolerance in any rotation entry;
tests check every quantity of both against each other (tests/dynamics/test_speed_paths.py).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from robotgen.model.chain import KinematicTree
from robotgen.numeric import exact

SNAP_TOLERANCE = 1e-9


def _snap_values(a: np.ndarray, tol: float) -> np.ndarray:
    out = a.copy()
    for target in (0.0, 1.0, -1.0):
        out[np.abs(out - target) < tol] = target
    return out


def snap_rotation(T: np.ndarray, tol: float = SNAP_TOLERANCE) -> np.ndarray:
    R = _snap_values(T[:3, :3], tol)
    if np.abs(exact.add(exact.matmul(R, R.T), (-1.0, np.eye(3)))).max() > 1e-15:
        return T
    out = T.copy()
    out[:3, :3] = R
    out[:3, 3] = np.where(np.abs(T[:3, 3]) < tol, 0.0, T[:3, 3])
    return out


def snap_axis(axis: np.ndarray, tol: float = SNAP_TOLERANCE) -> np.ndarray:
    a = _snap_values(axis, tol)
    return exact.unit(a)


def snap_tree(tree: KinematicTree, tol: float = SNAP_TOLERANCE) -> KinematicTree:
    joints = tuple(dataclasses.replace(j, origin=snap_rotation(j.origin, tol), axis=snap_axis(j.axis, tol))
                   for j in tree.joints)
    return dataclasses.replace(tree, joints=joints, tool=snap_rotation(tree.tool, tol))
