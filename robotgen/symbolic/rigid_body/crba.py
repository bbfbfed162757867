"""Joint-space inertia matrix by the composite rigid body algorithm (Walker and Orin 1982;
Featherstone 2008, Table 6.2), plus the motor armature on the diagonal."""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.kinematics import JointMotion
from robotgen.symbolic.rigid_body.spatial import force_transform_to_parent


def crba(tree: KinematicTree, motions: list[JointMotion], inertias: list[OriginInertia]) -> ca.SX:
    """``inertias``: each body's, about its joint's origin (regrouped or not)."""
    n = tree.n_joints
    composite = list(inertias)
    for i in reversed(range(n)):
        p = tree.joints[i].parent
        if p >= 0:
            composite[p] = composite[p] + composite[i].to_parent(motions[i])
    M = ca.SX.zeros(n, n)
    for i in range(n):
        m = motions[i]
        n_f, f_f = composite[i].apply(m.S_w, m.S_v)
        M[i, i] = ca.dot(m.S_w, n_f) + ca.dot(m.S_v, f_f) + tree.joints[i].armature
        j = i
        while tree.joints[j].parent >= 0:
            n_f, f_f = force_transform_to_parent(motions[j], n_f, f_f)
            j = tree.joints[j].parent
            M[i, j] = M[j, i] = ca.dot(motions[j].S_w, n_f) + ca.dot(motions[j].S_v, f_f)
    return M
