"""Inverse dynamics by the recursive Newton-Euler algorithm (Luh, Walker, Paul 1980), in
spatial-vector form (Featherstone 2008, Table 5.1), each body's force from its inertia about
its frame origin. Gravity enters as a base acceleration -g; the armature
and friction terms of each joint are added to its torque."""
from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion
from robotgen.symbolic.rigid_body.spatial import (
    const,
    force_transform_to_parent,
    motion_cross,
    motion_transform,
)

Motion = tuple[ca.SX, ca.SX]  # (angular; linear) in a body frame


def forward_pass(tree: KinematicTree, motions: list[JointMotion], qd: ca.SX | None, qdd: ca.SX | None,
                 gravity: bool = True) -> tuple[list[Motion], list[Motion]]:
    """Spatial velocity and acceleration of every body in its own frame (the first pass of
    RNEA). With gravity, the base accelerates at -g, so every acceleration carries it."""
    zero = ca.SX.zeros(3, 1)
    a_base = (zero, -const(tree.gravity)) if gravity else (zero, zero)
    vel: list[Motion] = []
    acc: list[Motion] = []
    for i, (joint, m) in enumerate(zip(tree.joints, motions)):
        vp, ap = ((zero, zero), a_base) if joint.parent < 0 else (vel[joint.parent], acc[joint.parent])
        w, v = motion_transform(m, *vp)
        aw, av = motion_transform(m, *ap)
        if qd is not None:
            w, v = w + m.S_w * qd[i], v + m.S_v * qd[i]
            cw, cv = motion_cross(w, v, m.S_w * qd[i], m.S_v * qd[i])
            aw, av = aw + cw, av + cv
        if qdd is not None:
            aw, av = aw + m.S_w * qdd[i], av + m.S_v * qdd[i]
        vel.append((w, v))
        acc.append((aw, av))
    return vel, acc


def body_force(I: OriginInertia, w: ca.SX, v: ca.SX, aw: ca.SX, av: ca.SX) -> tuple[ca.SX, ca.SX]:
    """The force (moment about the frame origin; force) I a + v x* I v that moves a body of
    inertia I = (m, h, Ibar) about the frame origin with spatial velocity (w, v) and
    acceleration (aw, av), written with the origin's classical acceleration a0 = av + w x v:
    f = m a0 + aw x h + w x (w x h), n = Ibar aw + w x Ibar w + h x a0. Linear in (m, h, Ibar),
    so regrouped parameters (robotgen.model.regrouping) serve as well as a body's, and their
    zeros (m = 0 for a revolute joint's body) drop terms."""
    a0 = av + ca.cross(w, v)
    f = I.m * a0 + ca.cross(aw, I.h) + ca.cross(w, ca.cross(w, I.h))
    return I.Ibar @ aw + ca.cross(w, I.Ibar @ w) + ca.cross(I.h, a0), f


def rnea(tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia], qd: ca.SX | None,
         qdd: ca.SX | None, gravity: bool = True, passes: tuple[list[Motion], list[Motion]] | None = None) -> ca.SX:
    """Rigid-body joint torques M qdd + C qd + g (no armature, no friction). ``qd`` or
    ``qdd`` None means zero, so that gravity alone and C qd + g stay small graphs.
    ``passes``: the forward pass if already built (shared with the tip acceleration)."""
    n = tree.nq
    vel, acc = passes or forward_pass(tree, motions, qd, qdd, gravity)
    force = [list(body_force(I, w, v, aw, av)) for I, (w, v), (aw, av) in zip(inertias, vel, acc)]
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
