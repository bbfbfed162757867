"""Inverse dynamics by the recursive Newton-Euler algorithm (Luh, Walker, Paul 1980), in
spatial-vector form (Featherstone 2008, Table 5.1), each body's force from Newton's and Euler's
equations about its centre of mass. Gravity enters as a base acceleration -g; the armature
and friction terms of each joint are added to its torque."""
from __future__ import annotations

import casadi as ca

from robotgen.model.chain import Body, KinematicTree
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


def body_force(body: Body, w: ca.SX, v: ca.SX, aw: ca.SX, av: ca.SX) -> tuple[ca.SX, ca.SX]:
    """The force (moment about the frame origin; force) that moves ``body`` with spatial
    velocity (w, v) and acceleration (aw, av): I a + v x* I v, written about the centre of mass
    c as Newton's and Euler's equations (Luh, Walker, Paul 1980): the COM accelerates at
    a_c = av + aw x c + w x (v + w x c), f = m a_c, and n = I_c aw + w x I_c w + c x f.
    The same numbers as the spatial form with about 10% fewer operations (the Panda's C qd + N:
    883 against 961; the UR5's 460 against 529)."""
    c, Ic = const(body.com), const(body.inertia)
    f = body.mass * (av + ca.cross(aw, c) + ca.cross(w, v + ca.cross(w, c)))
    return Ic @ aw + ca.cross(w, Ic @ w) + ca.cross(c, f), f


def rnea(tree: KinematicTree, motions: list[JointMotion], qd: ca.SX | None, qdd: ca.SX | None,
         gravity: bool = True, passes: tuple[list[Motion], list[Motion]] | None = None) -> ca.SX:
    """Rigid-body joint torques M qdd + C qd + g (no armature, no friction). ``qd`` or
    ``qdd`` None means zero, so that gravity alone and C qd + g stay small graphs.
    ``passes``: the forward pass if already built (shared with the tip acceleration)."""
    n = tree.nq
    vel, acc = passes or forward_pass(tree, motions, qd, qdd, gravity)
    force = [list(body_force(joint.body, w, v, aw, av)) for joint, (w, v), (aw, av) in zip(tree.joints, vel, acc)]
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
