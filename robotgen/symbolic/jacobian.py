"""Geometric Jacobian of the tip by vector cross products (Whitney 1972, eqs 7-9)."""
from __future__ import annotations

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.kinematics import joint_motions, joint_poses, tip_pose
from robotgen.symbolic.spatial import const


def geometric_jacobian(tree: KinematicTree, q: ca.SX) -> ca.SX:
    """6 x nq, rows [v; omega] of the tip frame origin in base coordinates.

    Revolute joint i (eq 8): column (z_i x (p_tip - p_i); z_i).
    Prismatic joint i (eq 9): column (z_i; 0).
    Joints that do not support the tip give zero columns."""
    poses = joint_poses(tree, joint_motions(tree, q))
    _, p_tip = tip_pose(tree, poses)
    columns = [ca.SX.zeros(6, 1) for _ in range(tree.nq)]
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


def jacobian_dot_qd(J: ca.SX, q: ca.SX, qd: ca.SX) -> ca.SX:
    """Jdot(q, qd) qd = d/dq (J(q) qd) . qd, by forward-mode AD (the tip's acceleration
    at qdd = 0)."""
    return ca.jtimes(J @ qd, q, qd)
