"""The Coriolis matrix from Christoffel symbols of the first kind (Spong and Vidyasagar 1989),
which makes Mdot - 2C skew-symmetric (Deno et al. 1990, eq 2.1): from M, or from the
Coriolis forces C qd alone."""

from __future__ import annotations

import casadi as ca


def coriolis_matrix(M: ca.SX, q: ca.SX, qd: ca.SX) -> ca.SX:
    """C_kj = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) qd_i
    = 1/2 (Mdot + B - B^T),  Mdot = sum_i dM/dq_i qd_i,  B = d(M qd)/dq."""
    Mdot = ca.jtimes(M, q, qd)
    B = ca.jacobian(M @ qd, q)
    return 0.5 * (Mdot + B - B.T)


def coriolis_from_forces(half_forces: ca.SX, qd: ca.SX) -> ca.SX:
    """The same C from the Coriolis forces h = C(q, qd) qd (Newton-Euler without gravity,
    qdd = 0): h_k = sum_ij c_kij qd_i qd_j with c_kij = c_kji, so dh_k/dqd_j = 2 C_kj. Takes
    h/2, computed on half the inertias (exact in floating point; the 1/2 folds into the
    constants). A forward sweep of the velocity pass per joint; no derivative of M."""
    return ca.jtimes(half_forces, qd, ca.SX.eye(qd.numel()))
