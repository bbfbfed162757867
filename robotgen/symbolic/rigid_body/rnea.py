"""Inverse dynamics by the recursive Newton-Euler algorithm (Luh, Walker, Paul 1980): the
forward pass carries each body's angular velocity and acceleration and its frame origin's
classical (linear) acceleration, with no linear velocity; each body's force comes from its
inertia about that origin, and the backward pass sums them to the base as spatial forces
(Featherstone 2008, Table 5.1). Gravity enters as a base acceleration -g; the armature
and friction terms of each joint are added to its torque."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca

from robotgen.model.chain import PRISMATIC, KinematicTree
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion
from robotgen.symbolic.rigid_body.spatial import const, force_transform_to_parent


@dataclass(frozen=True, eq=False)
class BodyMotion:
    """One body in its own frame: angular velocity w and acceleration aw, and a, the
    classical acceleration of the frame origin (the second derivative of its position)."""

    w: ca.SX
    aw: ca.SX
    a: ca.SX

    @cached_property
    def U(self) -> ca.SX:
        """U = [aw x] + [w x]^2 = [aw x] + w w^T - |w|^2 1, so that a point of the body at x
        from the origin accelerates at a + U x (Khalil and Kleinfinger's U_j): formed once,
        it serves the body's force and its children's origins. Built entry by entry."""
        w, aw = self.w, self.aw
        U = ca.SX.zeros(3, 3)
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            U[i, i] = -(w[j] * w[j] + w[k] * w[k])
            U[i, j] = w[i] * w[j] - aw[k]
            U[j, i] = w[i] * w[j] + aw[k]
        return U


def forward_pass(
    tree: KinematicTree, motions: list[JointMotion], qd: ca.SX | None, qdd: ca.SX | None, gravity: bool = True
) -> list[BodyMotion]:
    """The first pass of RNEA. A joint's origin is a point of the parent body at r (parent
    coordinates), so it accelerates at a_p + aw_p x r + w_p x (w_p x r); a revolute joint
    adds qd S to w and (w x S qd + qdd S) to aw, a prismatic joint 2 w x S qd + qdd S to a.
    With gravity the base accelerates at -g, so every a carries it."""
    zero = ca.SX.zeros(3, 1)
    out: list[BodyMotion] = []
    for i, (joint, m) in enumerate(zip(tree.joints, motions)):
        if joint.parent < 0:
            w, aw, a = zero, zero, m.to_child(-const(tree.gravity)) if gravity else zero
        else:
            p = out[joint.parent]
            a = p.a + p.U @ m.r
            w, aw, a = m.to_child(p.w), m.to_child(p.aw), m.to_child(a)
        prismatic = joint.type == PRISMATIC
        if qd is not None:
            if prismatic:
                a = a + 2 * ca.cross(w, m.S_v * qd[i])
            else:
                aw = aw + ca.cross(w, m.S_w * qd[i])
                w = w + m.S_w * qd[i]
        if qdd is not None:
            if prismatic:
                a = a + m.S_v * qdd[i]
            else:
                aw = aw + m.S_w * qdd[i]
        out.append(BodyMotion(w, aw, a))
    return out


def body_force(I: OriginInertia, b: BodyMotion) -> tuple[ca.SX, ca.SX]:
    """The force (moment about the frame origin; force) that moves a body of inertia
    I = (m, h = m c, Ibar) about its frame origin as ``b`` (Newton's and Euler's equations
    moved to the origin): f = m a + aw x h + w x (w x h), n = Ibar aw + w x Ibar w + h x a.
    Linear in (m, h, Ibar), so regrouped parameters (robotgen.model.regrouping) serve as well
    as a body's, and their zeros (m = 0 for a revolute joint's body) drop terms."""
    f = I.m * b.a + b.U @ I.h
    return I.Ibar @ b.aw + ca.cross(b.w, I.Ibar @ b.w) + ca.cross(I.h, b.a), f


def rnea(
    tree: KinematicTree,
    motions: list[JointMotion],
    inertias: list[OriginInertia],
    qd: ca.SX | None,
    qdd: ca.SX | None,
    gravity: bool = True,
    passes: list[BodyMotion] | None = None,
) -> ca.SX:
    """Rigid-body joint torques M qdd + C qd + g (no armature, no friction). ``qd`` or
    ``qdd`` None means zero, so that gravity alone and C qd + g stay small graphs.
    ``passes``: the forward pass if already built (shared with the tip acceleration)."""
    n = tree.n_joints
    passes = passes or forward_pass(tree, motions, qd, qdd, gravity)
    force = [list(body_force(I, b)) for I, b in zip(inertias, passes)]
    tau = [ca.SX(0)] * n
    for i in reversed(range(n)):
        m = motions[i]
        n_i, f_i = force[i]
        tau[i] = ca.dot(m.S_w, n_i) + ca.dot(m.S_v, f_i)
        p = tree.joints[i].parent
        if p >= 0:
            n_p, f_p = force_transform_to_parent(m, n_i, f_i)
            force[p][0] = force[p][0] + n_p
            force[p][1] = force[p][1] + f_p
    return ca.vertcat(*tau)
