"""The Coriolis matrix from Christoffel symbols of the first kind (Spong and Vidyasagar 1989),
which makes Mdot - 2C skew-symmetric (Deno et al. 1990, eq 2.1)."""
from __future__ import annotations

import casadi as ca


def coriolis_matrix(M: ca.SX, q: ca.SX, qd: ca.SX) -> ca.SX:
    """C_kj = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) qd_i
           = 1/2 (Mdot + B - B^T),  Mdot = sum_i dM/dq_i qd_i,  B = d(M qd)/dq."""
    Mdot = ca.jtimes(M, q, qd)
    B = ca.jacobian(M @ qd, q)
    return 0.5 * (Mdot + B - B.T)
