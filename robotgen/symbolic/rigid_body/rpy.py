"""Roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll), the fixed-axis angles of URDF and of Lee
and Lee 1983 (eq 2: alpha about x, beta about y, gamma about z of the reference frame), and
the map between their rates and the angular velocity (eqs 6-7)."""

from __future__ import annotations

import casadi as ca


def rpy_rotation(rpy: ca.SX) -> ca.SX:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (URDF's fixed-axis roll, pitch, yaw)."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (rpy[0], rpy[1], rpy[2]) for f in (ca.cos, ca.sin))
    return ca.vertcat(
        ca.horzcat(cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        ca.horzcat(sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        ca.horzcat(-sp, cp * sr, cp * cr),
    )


def rpy_rate_map(rpy: ca.SX) -> ca.SX:
    """E with omega (world) = E (roll, pitch, yaw rates): columns Rz Ry x, Rz y, z."""
    cp, sp, cy, sy = ca.cos(rpy[1]), ca.sin(rpy[1]), ca.cos(rpy[2]), ca.sin(rpy[2])
    return ca.vertcat(ca.horzcat(cy * cp, -sy, 0), ca.horzcat(sy * cp, cy, 0), ca.horzcat(-sp, 0, 1))


def rpy_of(R: ca.SX) -> ca.SX:
    """(roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-pi/2, pi/2]."""
    return ca.vertcat(
        ca.atan2(R[2, 1], R[2, 2]), ca.atan2(-R[2, 0], ca.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2)), ca.atan2(R[1, 0], R[0, 0])
    )


def rpy_rates(rpy: ca.SX, omega: ca.SX) -> ca.SX:
    """The rates (eq 7) of the angles for the angular velocity omega (base coordinates):
    E(rpy)^-1 omega, sec(pitch) times the cofactors. Singular where cos(pitch) = 0.

    The scanned eq 6 reads omega = -E rates: it takes R dR^T/dt for the angular velocity's
    cross matrix, which is dR/dt R^T with the sign flipped. Re-derived here so that omega is
    the hand's angular velocity, the same as the Jacobian's lower rows (eq 8)."""
    cp, sp, cy, sy = ca.cos(rpy[1]), ca.sin(rpy[1]), ca.cos(rpy[2]), ca.sin(rpy[2])
    wx, wy, wz = omega[0], omega[1], omega[2]
    roll_rate = (cy * wx + sy * wy) / cp
    pitch_rate = -sy * wx + cy * wy
    return ca.vertcat(roll_rate, pitch_rate, wz + sp * roll_rate)
