"""Snap the constants of a kinematic tree that are exact in intent and differ from it only in
their last bits.

A DH alpha of pi/2 (or a URDF rpy of 1.5707963267948966) gives rotation entries like
6.1e-17 where the designer meant 0, and 1 - 1.1e-16 where they meant 1. Left as they are,
every such entry multiplies through the symbolic algorithms as a non-zero and the emitted C
carries their products. An entry of a joint or tool rotation or of a joint axis is snapped to
0 or +-1 when it is within SNAP_ULPS units in the last place of 1 (the scale of a rotation's
entries) of it, a translation entry to 0 when it is within SNAP_ULPS units in the last place
of the translation's largest entry; a rotation only when the snapped one is still
orthonormal to 1e-15. So only the rounding of the arithmetic that made a constant is ever
removed: a rotation entry of 4.9e-12 (an rpy written as 1.57079632679, as the UR, Panda,
KUKA, Baxter and TIAGo files have it) or 1e-9 (romeo_laas_small's rpy) is what the file
says, and robotgen keeps it as every other reader does (Pinocchio to 1e-12 on every file).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from robotgen.model.chain import KinematicTree
from robotgen.numeric import exact

SNAP_ULPS = 4


def noise_bound(scale: float) -> float:
    """The largest deviation snapped on a constant whose entries have magnitude ``scale``:
    SNAP_ULPS units in its last place (8.9e-16 for a rotation's entries)."""
    return SNAP_ULPS * math.ulp(scale)


def _snap_values(a: np.ndarray, bound: float, targets: tuple[float, ...]) -> np.ndarray:
    out = a.copy()
    for target in targets:
        out[np.abs(out - target) <= bound] = target
    return out


def snap_rotation(T: np.ndarray) -> np.ndarray:
    """A (4, 4) transform with its rotation's near-0 and near-±1 entries snapped (if it stays orthonormal) and its
    translation's."""
    R = _snap_values(T[:3, :3], noise_bound(1.0), (0.0, 1.0, -1.0))
    if np.abs(exact.add(exact.matmul(R, R.T), (-1.0, np.eye(3)))).max() > 1e-15:
        return T
    out = T.copy()
    out[:3, :3] = R
    out[:3, 3] = _snap_values(T[:3, 3], noise_bound(float(np.abs(T[:3, 3]).max())), (0.0,))
    return out


def snap_axis(axis: np.ndarray) -> np.ndarray:
    """A (3,) joint axis with its near-0 and near-±1 entries snapped, made unit."""
    return exact.unit(_snap_values(axis, noise_bound(1.0), (0.0, 1.0, -1.0)))


def snap_tree(tree: KinematicTree) -> KinematicTree:
    """The tree with every joint origin, axis and the tool snapped."""
    joints = tuple(dataclasses.replace(j, origin=snap_rotation(j.origin), axis=snap_axis(j.axis)) for j in tree.joints)
    return dataclasses.replace(tree, joints=joints, tool=snap_rotation(tree.tool))
