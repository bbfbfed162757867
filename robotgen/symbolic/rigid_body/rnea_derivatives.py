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

from dataclasses import dataclass

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.rigid_body.friction import friction_torque
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion, joint_poses
from robotgen.symbolic.rigid_body.spatial import const, force_cross6, motion_cross6, skew
from robotgen.symbolic.schedule import ScheduleBuilder


@dataclass(frozen=True, eq=False)
class JointTerms:
    """Per joint (6-vectors as SX columns): S, Sdot, alpha, u = Ic S, w = the angular part of
    Bc^T S, gamma and lam (the ancestor rows' force terms); ``friction`` holds
    d tau_f,i / dqd_i (friction is diagonal); ``ancestors[i]`` the strict ancestors of i."""

    S: list[ca.SX]
    Sdot: list[ca.SX]
    alpha: list[ca.SX]
    u: list[ca.SX]
    w: list[ca.SX]
    gamma: list[ca.SX]
    lam: list[ca.SX]
    friction: ca.SX
    ancestors: list[set[int]]


def axes_and_inertias(
    tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia]
) -> tuple[list[ca.SX], list[OriginInertia]]:
    """Each joint's motion axis S and its body's inertia (``inertias``, about the joint's
    origin), about the base origin."""
    zero3 = ca.SX.zeros(3, 1)
    S, based = [], []
    for joint, inertia, (R, o) in zip(tree.joints, inertias, joint_poses(tree, motions)):
        z = R @ const(joint.axis)
        S.append(ca.vertcat(zero3, z) if joint.type == PRISMATIC else ca.vertcat(z, ca.cross(o, z)))
        based.append(inertia.in_frame(R, o))
    return S, based


def kinematics_stage(b: ScheduleBuilder, axes: list[ca.SX], inertias: list[OriginInertia]) -> tuple[int, int]:
    """Locals of a schedule holding axes_and_inertias (6 and 13 per joint), filled by the stage
    "kinematics": every looped kernel of a chain computes the same, so the C holds it once."""
    S, BODY = b.stage(
        "kinematics", [("axes", ca.horzcat(*axes)), ("inertias", ca.horzcat(*(x.vector() for x in inertias)))]
    )
    return S, BODY


def base_acceleration(tree: KinematicTree) -> ca.SX:
    """The base's spatial acceleration (6,): gravity as an upward acceleration, [0; -g]."""
    return ca.vertcat(ca.SX.zeros(3, 1), -const(tree.gravity))


def forward_step(v_p: ca.SX, a_p: ca.SX, S: ca.SX, qd: ca.SX, qdd: ca.SX) -> tuple[ca.SX, ...]:
    """(v, a, Sdot, alpha) of a joint from its parent's v and a."""
    v = v_p + S * qd
    Sdot = motion_cross6(v, S)
    a = a_p + S * qdd + Sdot * qd
    return v, a, Sdot, -motion_cross6(S, a_p) - motion_cross6(Sdot, v_p)


def body_terms(I: OriginInertia, v: ca.SX, a: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """(f = I a + v x* I v, T, p) of one body (T and p define its B, module docstring).
    [w x] Ibar - Ibar [w x] = X + X^T with X = [w x] Ibar (Ibar symmetric), and h nu^T + nu h^T
    is symmetric: each is formed from its upper triangle."""
    momentum = I.apply6(v)
    w, nu = v[:3], v[3:]
    X = skew(w) @ I.Ibar
    nh = ca.dot(nu, I.h)
    S = ca.SX.zeros(3, 3)
    for r in range(3):
        for c in range(r, 3):
            S[r, c] = X[r, c] + X[c, r] - (I.h[r] * nu[c] + nu[r] * I.h[c]) + (2 * nh if r == c else 0)
            S[c, r] = S[r, c]
    return I.apply6(a) + force_cross6(v, momentum), S - skew(momentum[:3]), momentum[3:]


def joint_outputs(
    Ic: OriginInertia, T: ca.SX, p: ca.SX, S: ca.SX, Sdot: ca.SX, F: ca.SX, alpha: ca.SX
) -> tuple[ca.SX, ...]:
    """(u, w, gamma, lam) of a joint from its subtree's composites Ic, T, p, F."""

    def B(y: ca.SX) -> ca.SX:  # Bc y
        return ca.vertcat(T @ y[:3], -2 * ca.cross(p, y[:3]))

    return (
        Ic.apply6(S),
        T.T @ S[:3] + 2 * ca.cross(p, S[3:]),
        force_cross6(S, F) + Ic.apply6(alpha) + B(Sdot),
        2 * Ic.apply6(Sdot) + B(S),
    )


def joint_terms(
    tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia], qd: ca.SX, qdd: ca.SX
) -> JointTerms:
    """The O(n) part of the recursion: everything the joint-pair terms read."""
    n = tree.n_joints
    S, Ic = axes_and_inertias(tree, motions, inertias)
    a_base = base_acceleration(tree)
    Sdot: list[ca.SX] = []
    v: list[ca.SX] = []
    a: list[ca.SX] = []
    alpha: list[ca.SX] = []
    F: list[ca.SX] = []
    T: list[ca.SX] = []
    p: list[ca.SX] = []
    for i, joint in enumerate(tree.joints):
        v_p, a_p = (ca.SX.zeros(6, 1), a_base) if joint.parent < 0 else (v[joint.parent], a[joint.parent])
        for lst, x in zip((v, a, Sdot, alpha), forward_step(v_p, a_p, S[i], qd[i], qdd[i])):
            lst.append(x)
        for lst, x in zip((F, T, p), body_terms(Ic[i], v[i], a[i])):
            lst.append(x)
    for i in reversed(range(n)):  # composites: subtree sums
        parent = tree.joints[i].parent
        if parent >= 0:
            F[parent] = F[parent] + F[i]
            Ic[parent] = Ic[parent] + Ic[i]
            T[parent] = T[parent] + T[i]
            p[parent] = p[parent] + p[i]
    u, w, gamma, lam = (
        list(x) for x in zip(*(joint_outputs(Ic[i], T[i], p[i], S[i], Sdot[i], F[i], alpha[i]) for i in range(n)))
    )
    ancestors: list[set[int]] = []
    for joint in tree.joints:
        ancestors.append(set() if joint.parent < 0 else ancestors[joint.parent] | {joint.parent})
    friction = ca.diag(ca.jacobian(friction_torque(tree, qd), qd))
    return JointTerms(S, Sdot, alpha, u, w, gamma, lam, friction, ancestors)


def subtree_term(u_i: ca.SX, w_i: ca.SX, alpha_j: ca.SX, Sdot_j: ca.SX, S_j: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(d tau_i/dq_j, d tau_i/dqd_j) for i in the subtree of j."""
    return (ca.dot(u_i, alpha_j) + ca.dot(w_i, Sdot_j[:3]), 2 * ca.dot(u_i, Sdot_j) + ca.dot(w_i, S_j[:3]))


def ancestor_term(S_i: ca.SX, gamma_j: ca.SX, lam_j: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(d tau_i/dq_j, d tau_i/dqd_j) for i a strict ancestor of j."""
    return ca.dot(S_i, gamma_j), ca.dot(S_i, lam_j)


def rnea_derivatives(
    tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia], qd: ca.SX, qdd: ca.SX
) -> tuple[ca.SX, ca.SX]:
    """(d tau / dq, d tau / dqd) of inverse dynamics with friction (the armature term
    depends on qdd only)."""
    n = tree.n_joints
    t = joint_terms(tree, motions, inertias, qd, qdd)
    dq = ca.SX.zeros(n, n)
    dqd = ca.SX.zeros(n, n)
    for j in range(n):
        for i in range(n):
            if i == j or j in t.ancestors[i]:
                dq[i, j], dqd[i, j] = subtree_term(t.u[i], t.w[i], t.alpha[j], t.Sdot[j], t.S[j])
            elif i in t.ancestors[j]:
                dq[i, j], dqd[i, j] = ancestor_term(t.S[i], t.gamma[j], t.lam[j])
    return dq, dqd + ca.diag(t.friction)


def is_serial(tree: KinematicTree) -> bool:
    """Each joint's parent is the joint before it: the subtree of j is i >= j."""
    return all(joint.parent == i - 1 for i, joint in enumerate(tree.joints))
