"""The Christoffel-consistent Coriolis matrix in O(n^2) from spatial quantities
(Echeandia and Wensing 2021, "Numerical methods to compute the Coriolis matrix and
Christoffel symbols for rigid-body systems"), for large trees where differentiating M
(O(n^3) terms) makes the graph too big.

In world coordinates, with S_j the motion subspace of joint j, v_k the spatial velocity
of body k, I_k its spatial inertia and B_k = 1/2 [(v_k x*) I_k - I_k (v_k x) + (I_k v_k) x-bar]
(so that B_k + B_k^T = dI_k/dt), the matrix C = sum_k J_k^T (B_k J_k + I_k dJ_k/dt) has
Mdot - 2C skew and C qd the Coriolis forces. Collecting the bodies of each subtree
(composite B^C, I^C) gives, with dS_j/dt = v_j x S_j:
    C_ij = S_i^T (B^C_i S_j + I^C_i dS_j)   for j an ancestor of i or i itself,
    C_ij = S_i^T (B^C_j S_j + I^C_j dS_j)   for i an ancestor of j.
The armature has no velocity dependence and adds nothing."""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion, joint_poses
from robotgen.symbolic.rigid_body.spatial import const, skew


def _motion_cross(v: ca.SX) -> ca.SX:
    """6x6 (v x) for motion vectors (angular; linear)."""
    w, u = skew(v[:3]), skew(v[3:])
    return ca.blockcat([[w, ca.SX.zeros(3, 3)], [u, w]])


def _force_cross_bar(f: ca.SX) -> ca.SX:
    """6x6 matrix of m -> m x* f (skew-symmetric)."""
    n, g = skew(f[:3]), skew(f[3:])
    return ca.blockcat([[-n, -g], [-g, ca.SX.zeros(3, 3)]])


def _world_inertia(inertia: OriginInertia, R: ca.SX, p: ca.SX) -> ca.SX:
    """6x6 spatial inertia about the world origin of a body whose frame is (R, p)."""
    I = inertia.in_frame(R, p)
    hx = skew(I.h)
    return ca.blockcat([[I.Ibar, hx], [hx.T, I.m * ca.SX.eye(3)]])


def coriolis_spatial(
    tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia], qd: ca.SX
) -> ca.SX:
    """C(q, qd) (n, n) by the O(n^2) spatial algorithm, Christoffel-consistent."""
    n = tree.n_joints
    poses = joint_poses(tree, motions)
    S: list[ca.SX] = []
    v: list[ca.SX] = []
    dS: list[ca.SX] = []
    I: list[ca.SX] = []
    for i, (joint, (R, p)) in enumerate(zip(tree.joints, poses)):
        z = R @ const(joint.axis)
        Si = ca.vertcat(ca.SX.zeros(3, 1), z) if joint.type == PRISMATIC else ca.vertcat(z, ca.cross(p, z))
        vi = Si * qd[i] if joint.parent < 0 else v[joint.parent] + Si * qd[i]
        S.append(Si)
        v.append(vi)
        dS.append(_motion_cross(vi) @ Si)
        I.append(_world_inertia(inertias[i], R, p))
    B = []
    for k in range(n):
        Iv = I[k] @ v[k]
        vx = _motion_cross(v[k])
        B.append(0.5 * (-vx.T @ I[k] - I[k] @ vx + _force_cross_bar(Iv)))
    IC, BC = list(I), list(B)  # composite: sums over each subtree
    for k in reversed(range(n)):
        parent = tree.joints[k].parent
        if parent >= 0:
            IC[parent] = IC[parent] + IC[k]
            BC[parent] = BC[parent] + BC[k]
    C = ca.SX.zeros(n, n)
    for i in range(n):
        a_i, b_i = BC[i].T @ S[i], IC[i] @ S[i]  # C_ij = a_i . S_j + b_i . dS_j for ancestors j
        f_i = BC[i] @ S[i] + IC[i] @ dS[i]  # C_ji = S_j . f_i for strict ancestors j
        j = i
        while j >= 0:
            C[i, j] = ca.dot(a_i, S[j]) + ca.dot(b_i, dS[j])
            if j != i:
                C[j, i] = ca.dot(S[j], f_i)
            j = tree.joints[j].parent
    return C
