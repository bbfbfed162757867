"""The tip's kinematics with the first joint's turn factored out.

When the tip's chain starts at a revolute joint whose axis line passes through the base
origin (a vertical first axis, as on most arms), turning that joint by q_0 turns everything
beyond it about that line: the tip pose, its Jacobian (Whitney 1972, eqs 7-9) and its bias
acceleration Jdot qd are those at q_0 = 0, turned by R(q_0). Which form CSE leaves smaller
depends on the arm, so ChainGraphs counts both."""

from __future__ import annotations

import casadi as ca
import numpy as np

from robotgen.model.chain import REVOLUTE, KinematicTree
from robotgen.model.snap import noise_bound, snap_axis
from robotgen.symbolic.rigid_body.spatial import axis_rotation


def base_axis(tree: KinematicTree) -> tuple[int, np.ndarray] | None:
    """(joint index, unit axis in base coordinates) of the revolute joint at the root of the
    tip's chain when its axis line passes through the base origin (to the rounding of its
    constants, model/snap.py); None otherwise."""
    root = tree.support(tree.tip)[0]
    joint = tree.joints[root]
    if joint.type != REVOLUTE:
        return None
    axis = snap_axis(joint.origin[:3, :3] @ joint.axis)
    offset = joint.origin[:3, 3]
    if np.linalg.norm(np.cross(axis, offset)) > noise_bound(max(1.0, float(np.linalg.norm(offset)))):
        return None
    return root, axis


def turned(tree: KinematicTree, q: ca.SX, expr: ca.SX, blocks: int) -> ca.SX | None:
    """``expr`` (3 * blocks rows of base-frame vectors, or a 4 x 4 pose when blocks is 0)
    evaluated at q_root = 0 and turned by R(q_root); None when base_axis is None."""
    found = base_axis(tree)
    if found is None:
        return None
    root, axis = found
    R = axis_rotation(axis, ca.cos(q[root]), ca.sin(q[root]))
    at_zero = ca.substitute(expr, q[root], ca.SX(0))
    if blocks == 0:  # homogeneous pose
        return ca.vertcat(ca.horzcat(R @ at_zero[:3, :3], R @ at_zero[:3, 3]), at_zero[3, :])
    return ca.vertcat(*(R @ at_zero[3 * k : 3 * k + 3, :] for k in range(blocks)))
