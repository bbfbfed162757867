"""Geometric Jacobian of the tip by vector cross products (Whitney 1972, eqs 7-9)."""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.rigid_body.kinematics import joint_motions, joint_poses, tip_pose
from robotgen.symbolic.rigid_body.spatial import const


def geometric_jacobian(tree: KinematicTree, q: ca.SX) -> ca.SX:
    """6 x nq, rows [v; omega] of the tip frame origin in base coordinates.

    Revolute joint i (eq 8): column (z_i x (p_tip - p_i); z_i).
    Prismatic joint i (eq 9): column (z_i; 0).
    Joints that do not support the tip give zero columns."""
    poses = joint_poses(tree, joint_motions(tree, q))
    _, p_tip = tip_pose(tree, poses)
    columns = [ca.SX.zeros(6, 1) for _ in range(tree.n_joints)]
    for i in tree.support(tree.tip):
        R, p = poses[i]
        z = R @ const(tree.joints[i].axis)
        if tree.joints[i].type == PRISMATIC:
            columns[i] = ca.vertcat(z, ca.SX.zeros(3, 1))
        else:
            columns[i] = ca.vertcat(ca.cross(z, p_tip - p), z)
    return ca.horzcat(*columns)


def hand_jacobian(tree: KinematicTree, q: ca.SX) -> ca.SX:
    """The same rates in tip-frame coordinates (eq 7): blockdiag(R^T, R^T) J."""
    R, _ = tip_pose(tree, joint_poses(tree, joint_motions(tree, q)))
    J = geometric_jacobian(tree, q)
    return ca.vertcat(R.T @ J[:3, :], R.T @ J[3:, :])


def tip_bias_acceleration(tree: KinematicTree, poses: list[tuple[ca.SX, ca.SX]], passes: list) -> ca.SX:
    """Jdot qd from RNEA's forward pass at qdd = 0 (rnea.BodyMotion, with the base accelerating
    at -g): the tip origin p (in the frame of joint ``tip``) accelerates at a + U p (U the
    body's BodyMotion.U); rotated to the base, with g added back."""
    b = passes[tree.tip]
    a = b.a + b.U @ const(tree.tool[:3, 3])
    R, _ = poses[tree.tip]
    return ca.vertcat(R @ a + const(tree.gravity), R @ b.aw)
