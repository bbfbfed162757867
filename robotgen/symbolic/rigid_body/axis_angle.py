"""The rotation that carries the hand from C7(theta_i) to C7(theta_f) (Whitney 1972, eqs 13-18).

C_if = C7(theta_i)^T C7(theta_f) (eq 14) turns frame 7 about an axis Omega that it leaves
unchanged, C_if Omega = Omega (eq 15), through an angle alpha measured in the plane normal to
Omega (eqs 16-18). Done robustly for every angle:

- Omega: for alpha < pi/2 the normalised skew part u = vee(C - C^T) / 2 = sin(alpha) Omega;
  beyond, where u vanishes towards pi, the largest column of the symmetric part
  (C + C^T) / 2 - cos(alpha) I = (1 - cos alpha) Omega Omega^T, signed to agree with u.
- alpha: eq 18, cos alpha = (e_k^T C e_k - Omega_k^2) / (1 - Omega_k^2), with the reference
  hand axis e_k the one least aligned with Omega. Whitney's X is replaced by Y when Omega
  lies along X ("this formula is inapplicable"); choosing the least aligned axis keeps
  1 - Omega_k^2 >= 2/3 always. sin alpha = Omega^T u >= 0, alpha = atan2(sin, cos) in
  [0, pi], exact at pi (where either sign of Omega is correct).
"""

from __future__ import annotations

import casadi as ca


def _argmax_select(keys: list[ca.SX], values: list[ca.SX]) -> ca.SX:
    """values[k] for the k with the largest keys[k] (the first on ties)."""
    best_key, best = keys[0], values[0]
    for key, value in zip(keys[1:], values[1:]):
        better = key > best_key
        best = ca.if_else(better, value, best)
        best_key = ca.if_else(better, key, best_key)
    return best


def axis_and_angle(C: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(Omega, alpha) of a rotation matrix C (eqs 15-18): C Omega = Omega, |Omega| = 1,
    alpha in [0, pi]."""
    u = 0.5 * ca.vertcat(C[2, 1] - C[1, 2], C[0, 2] - C[2, 0], C[1, 0] - C[0, 1])
    s = ca.norm_2(u)
    c = ca.fmin(ca.fmax((C[0, 0] + C[1, 1] + C[2, 2] - 1) / 2, -1), 1)
    # small and moderate angles: Omega along u (any unit vector when the rotation is zero)
    small = ca.if_else(s > 0, u / ca.if_else(s > 0, s, 1), ca.vertcat(1, 0, 0))
    # large angles: the dominant column of (1 - cos) Omega Omega^T
    B = 0.5 * (C + C.T) - c * ca.SX.eye(3)
    column = _argmax_select([B[k, k] for k in range(3)], [B[:, k] for k in range(3)])
    column = column / ca.norm_2(column)
    large = ca.if_else(ca.dot(column, u) < 0, -column, column)
    omega = ca.if_else(c > 0, small, large)
    # eq 18 about the hand axis least aligned with Omega (eq 18's special case, generalised)
    a = [ca.fabs(omega[k]) for k in range(3)]
    cos_k = [(C[k, k] - omega[k] ** 2) / (1 - omega[k] ** 2) for k in range(3)]
    cos_alpha = _argmax_select([-a[k] for k in range(3)], cos_k)
    sin_alpha = ca.dot(omega, u)
    alpha = ca.atan2(ca.fmax(sin_alpha, 0), cos_alpha)
    return omega, alpha


def rotation_vector(C: ca.SX) -> ca.SX:
    """alpha Omega in the coordinates of C's own (initial) frame."""
    omega, alpha = axis_and_angle(C)
    return alpha * omega
