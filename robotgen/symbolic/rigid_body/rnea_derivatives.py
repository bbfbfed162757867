"""The partial derivatives of inverse dynamics, d tau / dq and d tau / dqd, by a recursion over
the kinematic tree in base-frame spatial vectors: O(n) spatial quantities, then one pair of
6-vector dot products per joint pair.

Base coordinates, spatial vectors (angular; linear) about the base origin. For joint j with
parent lambda(j): S_j its motion axis, v_j and a_j the body's velocity and acceleration
(a_0 = -g), Sdot_j = v_j x S_j, f_j = I_j a_j + v_j x* I_j v_j and F_j the sum of f over the
subtree of j; tau_j = S_j . F_j. A change of q_j turns the subtree of j about S_j, so every
quantity of a body k in that subtree moves as the rigid motion S_j x (.), except v_k and a_k,
which change by Sdot_j and alpha_j + Sdot_j x v_k in addition, with

    alpha_j = -S_j x a_lambda(j) - Sdot_j x v_lambda(j).

Summed over the subtree, with the composite inertia Ic_j and Bc_j = sum over k of B_k,
B_k y = v_k x* (I_k y) - I_k (v_k x y) + y x* (I_k v_k):

    i in the subtree of j:   d tau_i / dq_j  = (Ic_i S_i) . alpha_j + (Bc_i^T S_i) . Sdot_j
                             d tau_i / dqd_j = 2 (Ic_i S_i) . Sdot_j + (Bc_i^T S_i) . S_j
    i a strict ancestor:     d tau_i / dq_j  = S_i . (S_j x* F_j + Ic_j alpha_j + Bc_j Sdot_j)
                             d tau_i / dqd_j = S_i . (2 Ic_j Sdot_j + Bc_j S_j)
    otherwise 0.

(In the first case the rigid turn of S_i and of F_i cancel.) B_k reduces to
[[T_k, 0], [-2 [p_k x], 0]] with p_k the body's linear momentum and the 3x3
T_k = [w x] Ibar - Ibar [w x] - (h nu^T + nu h^T - 2 (nu . h) 1) - [l x], for v_k = (w; nu),
the inertia about the base origin (m, h = m c, Ibar) and angular momentum l: B_k reads only
the angular part of the vector it is applied to. The same quantities are those of the
analytical derivatives of Carpentier and Mansard (RSS 2018), written here in this form."""
from __future__ import annotations

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.rigid_body.friction import friction_torque
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion, joint_poses
from robotgen.symbolic.rigid_body.spatial import const, force_cross, motion_cross, skew


def _motion_cross(a: ca.SX, b: ca.SX) -> ca.SX:
    """spatial.motion_cross on stacked 6-vectors."""
    return ca.vertcat(*motion_cross(a[:3], a[3:], b[:3], b[3:]))


def _force_cross(a: ca.SX, f: ca.SX) -> ca.SX:
    return ca.vertcat(*force_cross(a[:3], a[3:], f[:3], f[3:]))


def _apply(inertia: OriginInertia, x: ca.SX) -> ca.SX:
    return ca.vertcat(*inertia.apply(x[:3], x[3:]))


def rnea_derivatives(tree: KinematicTree, motions: list[JointMotion], qd: ca.SX, qdd: ca.SX
                     ) -> tuple[ca.SX, ca.SX]:
    """(d tau / dq, d tau / dqd) of inverse dynamics with friction (the armature term
    depends on qdd only)."""
    n = tree.nq
    poses = joint_poses(tree, motions)
    zero3 = ca.SX.zeros(3, 1)
    a_base = ca.vertcat(zero3, -const(tree.gravity))
    S, Sdot, v, a, alpha, F, Ic, T, p = [], [], [], [], [], [], [], [], []
    for i, (joint, (R, o)) in enumerate(zip(tree.joints, poses)):
        z = R @ const(joint.axis)
        S_i = ca.vertcat(zero3, z) if joint.type == PRISMATIC else ca.vertcat(z, ca.cross(o, z))
        v_p, a_p = (ca.SX.zeros(6, 1), a_base) if joint.parent < 0 else (v[joint.parent], a[joint.parent])
        v_i = v_p + S_i * qd[i]
        Sdot_i = _motion_cross(v_i, S_i)
        a_i = a_p + S_i * qdd[i] + Sdot_i * qd[i]
        I_i = OriginInertia.of_body(joint.body).in_frame(R, o)  # about the base origin
        momentum = _apply(I_i, v_i)
        w, nu = v_i[:3], v_i[3:]
        W = skew(w)
        T_i = (W @ I_i.Ibar - I_i.Ibar @ W - (I_i.h @ nu.T + nu @ I_i.h.T - 2 * ca.dot(nu, I_i.h) * ca.SX.eye(3))
               - skew(momentum[:3]))
        S.append(S_i)
        Sdot.append(Sdot_i)
        v.append(v_i)
        a.append(a_i)
        alpha.append(-_motion_cross(S_i, a_p) - _motion_cross(Sdot_i, v_p))
        F.append(_apply(I_i, a_i) + _force_cross(v_i, momentum))
        Ic.append(I_i)
        T.append(T_i)
        p.append(momentum[3:])
    for i in reversed(range(n)):  # composites: subtree sums
        parent = tree.joints[i].parent
        if parent >= 0:
            F[parent] = F[parent] + F[i]
            Ic[parent] = Ic[parent] + Ic[i]
            T[parent] = T[parent] + T[i]
            p[parent] = p[parent] + p[i]

    def B(j: int, y: ca.SX) -> ca.SX:  # Bc_j y
        return ca.vertcat(T[j] @ y[:3], -2 * ca.cross(p[j], y[:3]))

    u = [_apply(Ic[i], S[i]) for i in range(n)]  # Ic_i S_i
    w_ = [T[i].T @ S[i][:3] + 2 * ca.cross(p[i], S[i][3:]) for i in range(n)]  # angular part of Bc_i^T S_i
    ancestors: list[set[int]] = []
    for joint in tree.joints:
        ancestors.append(set() if joint.parent < 0 else ancestors[joint.parent] | {joint.parent})
    dq = ca.SX.zeros(n, n)
    dqd = ca.SX.zeros(n, n)
    for j in range(n):
        gamma = _force_cross(S[j], F[j]) + _apply(Ic[j], alpha[j]) + B(j, Sdot[j])
        lam = 2 * _apply(Ic[j], Sdot[j]) + B(j, S[j])
        for i in range(n):
            if i == j or j in ancestors[i]:
                dq[i, j] = ca.dot(u[i], alpha[j]) + ca.dot(w_[i], Sdot[j][:3])
                dqd[i, j] = 2 * ca.dot(u[i], Sdot[j]) + ca.dot(w_[i], S[j][:3])
            elif i in ancestors[j]:
                dq[i, j] = ca.dot(S[i], gamma)
                dqd[i, j] = ca.dot(S[i], lam)
    return dq, dqd + ca.jacobian(friction_torque(tree, qd), qd)
