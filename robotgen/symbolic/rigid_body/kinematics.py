"""Forward kinematics of a KinematicTree: per-joint rigid motions and base-frame poses."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree, coordinate_axis
from robotgen.symbolic.rigid_body.spatial import axis_rotation, const, homogeneous, rotate_symmetric


@dataclass(frozen=True, eq=False)
class JointMotion:
    """Joint i relative to its parent at configuration q: child orientation R = R0 Rm in
    parent coordinates, R0 the constant origin rotation and Rm the joint's own rotation
    (None for a prismatic joint); r the child origin in parent coordinates; S the motion
    subspace (angular; linear) in the child.

    Vectors are carried across the joint in two steps, the constant R0 (after snapping
    mostly a signed permutation, so free) and the sparse Rm (a rotation about the joint
    axis), which costs far fewer operations than one product with the dense R."""

    R0: ca.SX
    Rm: ca.SX | None
    r: ca.SX
    S_w: ca.SX
    S_v: ca.SX
    # about a coordinate axis: (k, cos q, sin q) of Rm as a turn about +e_k (sign folded in)
    turn: tuple[int, ca.SX, ca.SX] | None = None

    @property
    def R(self) -> ca.SX:
        """The joint's rotation R = R0 Rm (3, 3) in its parent."""
        return self.R0 if self.Rm is None else self.R0 @ self.Rm

    @property
    def E(self) -> ca.SX:
        """R^T, which maps parent coordinates into the joint's."""
        return self.R.T

    def to_child(self, v: ca.SX) -> ca.SX:
        """E v = Rm^T (R0^T v)."""
        u = self.R0.T @ v
        return u if self.Rm is None else self.Rm.T @ u

    def to_parent(self, v: ca.SX) -> ca.SX:
        """R v = R0 (Rm v)."""
        return self.R0 @ (v if self.Rm is None else self.Rm @ v)

    def turn_symmetric(self, X: ca.SX) -> ca.SX:
        """Rm X Rm^T for a symmetric X. About a coordinate axis k (plane i, j) by double
        angles, c2 = 2c^2 - 1 and s2 = 2cs shared by every use: with d = (X_ii - X_jj)/2,
        t = (X_ii + X_jj)/2 and e = c2 d - s2 X_ij, Y_ii = t + e, Y_jj = t - e,
        Y_ij = s2 d + c2 X_ij, (Y_ik, Y_jk) = (c X_ik - s X_jk, s X_ik + c X_jk), Y_kk = X_kk."""
        if self.Rm is None:
            return X
        if self.turn is None:
            return rotate_symmetric(self.Rm, X)
        k, c, s = self.turn
        i, j = (k + 1) % 3, (k + 2) % 3
        c2, s2 = 2 * (c * c) - 1, 2 * (c * s)
        d, t = 0.5 * (X[i, i] - X[j, j]), 0.5 * (X[i, i] + X[j, j])
        e = c2 * d - s2 * X[i, j]
        Y = ca.SX.zeros(3, 3)
        Y[i, i], Y[j, j] = t + e, t - e
        Y[i, j] = Y[j, i] = s2 * d + c2 * X[i, j]
        Y[i, k] = Y[k, i] = c * X[i, k] - s * X[j, k]
        Y[j, k] = Y[k, j] = s * X[i, k] + c * X[j, k]
        Y[k, k] = X[k, k]
        return Y

    def matrix_to_parent(self, X: ca.SX) -> ca.SX:
        """R X R^T, the rotation of a 3x3 tensor into parent coordinates."""
        Y = X if self.Rm is None else self.Rm @ X @ self.Rm.T
        return self.R0 @ Y @ self.R0.T


def joint_motions(tree: KinematicTree, q: ca.SX) -> list[JointMotion]:
    """One sin/cos pair per revolute joint, shared by every quantity built on it."""
    motions = []
    for i, joint in enumerate(tree.joints):
        R0 = const(joint.origin[:3, :3])
        p0 = const(joint.origin[:3, 3])
        axis = const(joint.axis)
        zero = ca.SX.zeros(3, 1)
        if joint.type == PRISMATIC:
            motions.append(JointMotion(R0, None, p0 + R0 @ axis * q[i], zero, axis))
        else:
            c, s = ca.cos(q[i]), ca.sin(q[i])
            Rm = axis_rotation(joint.axis, c, s)
            k = coordinate_axis(joint.axis)
            turn = None if k is None else (k, c, s if joint.axis[k] > 0 else -s)
            motions.append(JointMotion(R0, Rm, p0, axis, zero, turn))
    return motions


def joint_poses(tree: KinematicTree, motions: list[JointMotion]) -> list[tuple[ca.SX, ca.SX]]:
    """Base-frame orientation and origin of every joint frame."""
    poses: list[tuple[ca.SX, ca.SX]] = []
    for joint, m in zip(tree.joints, motions):
        if joint.parent < 0:
            poses.append((m.R, m.r))
        else:
            Rp, pp = poses[joint.parent]
            poses.append((Rp @ m.R, pp + Rp @ m.r))
    return poses


def tip_pose(tree: KinematicTree, poses: list[tuple[ca.SX, ca.SX]]) -> tuple[ca.SX, ca.SX]:
    """The tip pose with the tool: (R (3, 3), p (3,)) in the base frame."""
    R, p = poses[tree.tip]
    return R @ const(tree.tool[:3, :3]), p + R @ const(tree.tool[:3, 3])


def forward_kinematics(tree: KinematicTree, q: ca.SX) -> ca.SX:
    """4x4 homogeneous transform of the tip frame in the base frame."""
    R, p = tip_pose(tree, joint_poses(tree, joint_motions(tree, q)))
    return homogeneous(R, p)
