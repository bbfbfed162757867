"""Joint friction, part of N(q, qd) (Deno et al. 1990, eq 2.1): viscous plus a smooth
Coulomb term, tau_f = b qd + c tanh(qd / eps). tanh replaces sign(qd) so N stays
differentiable; eps is the spec's coulomb_smoothing."""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree


def friction_torque(tree: KinematicTree, qd: ca.SX) -> ca.SX:
    """Joint friction torques (n_joints,): viscous b qd plus Coulomb f tanh(qd / smoothing)."""
    terms = []
    for i, joint in enumerate(tree.joints):
        tau = ca.SX(0)
        if joint.viscous:
            tau = tau + joint.viscous * qd[i]
        if joint.coulomb:
            tau = tau + joint.coulomb * ca.tanh(qd[i] / tree.coulomb_smoothing)
        terms.append(tau)
    return ca.vertcat(*terms)
