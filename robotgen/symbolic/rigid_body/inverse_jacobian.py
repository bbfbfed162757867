"""The resolved motion maps of an arm with a spherical wrist (rigid_body/spherical_wrist.py),
qd = J^-1 [v; w] (Lee and Lee 1983, eq 11) and qdd = J^-1 ([vdot; wdot] - Jdot qd) (eq 13),
by two 3 x 3 solves: taken at the wrist centre c, the hand Jacobian is block lower triangular
(Melouah and Andre 1982, the paper's ref [22]), because joints 4-6 turn about lines through c.

With r = p - c (the hand origin from the wrist centre, fixed in the hand), the wrist centre
moves at v_c = v - w x r, and

    [v_c]   [J11   0 ] [qd_123]
    [ w ] = [J21  J22] [qd_456],     J11 = [w1 x (c - o1), w2 x (c - o2), w3 x (c - o3)],
                                     J21 = [w1, w2, w3],  J22 = [w4, w5, w6]

(w_i the axes, o_i points on them), so qd_123 = J11^-1 v_c and qd_456 = J22^-1 (w - J21 qd_123).
Differentiated, with a_c the wrist centre's acceleration, a_c = vdot - wdot x r - w x (w x r):
qdd_123 = J11^-1 (a_c - b_c) and qdd_456 = J22^-1 (wdot - b_w - J21 qdd_123), where b_c and b_w
are the wrist centre's and the hand's accelerations at qdd = 0 (Jdot qd, exactly).

Each block is solved where it is sparse:
- J11 in arm coordinates: body 1's, on the basis (e_u, e_v, w2) with axes 2 and 3 along the
  third vector. The wrist centre then moves as a planar two-link arm about o2,
  c - o2 = (P, h), P = D2 + Q, D2 = Rot(q2) D, Q = Rot(q2 + phi3) U (phi3 = +-q3), so the
  columns of joints 2 and 3 are w2 x P and w3 x Q, in the plane, and J11's w2 row is
  (g, 0, 0), g = w2 . (w1 x (c - o1)): x1 = v_w / g, then a 2 x 2 solve whose determinant
  is e = P x Q (the elbow). det J11 = +-g e.
- J22 in wrist coordinates: body 4's, on the basis (a, b, a x b) of axes 4 and 5 (a, b
  perpendicular): axis 6 is Rot(b, q5) c = (W_a, 0, W_ab), so x5 = y_b, x6 = y_ab / W_ab,
  x4 = y_a - W_a x6. det J22 = W_ab.
b_c is the planar arm's centripetal terms plus body 1's turn (Coriolis and centripetal,
in the rotating arm coordinates); b_w = sum_j omega_{j-1} x w_j qd_j (omega_j the angular
velocity of body j), the part of joints 1-3 being qd1 (qd2 +- qd3) w1 x w2.

Singularities: a block is taken as singular where |det| is below SINGULAR_DETERMINANT times
the product of its columns' norms (Hadamard's bound, so that the test is dimensionless):
J11's are |w1 x (c - o1)|, |P|, |U| (shoulder: the wrist centre over axis 1, g = 0; elbow
stretched or folded, e = 0); J22's are all 1 (wrist: axes 4 and 6 in line, W_ab = 0). Then
every joint rate and acceleration is NaN (a checked step returns status 2)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from robotgen.numeric import exact
from robotgen.symbolic.rigid_body.axis_turns import cross, dot, plane_turn, turn, turned_dot
from robotgen.symbolic.rigid_body.spherical_wrist import SphericalWristArm

# A 3 x 3 block is singular where |det| < SINGULAR_DETERMINANT * (product of its column norms).
SINGULAR_DETERMINANT = 1e-6


class WristCentreJacobian:
    """The two blocks of one arm's Jacobian at the wrist centre, solved (module docstring)."""

    def __init__(self, arm: SphericalWristArm):
        self.arm = arm
        self.basis = np.array([arm.plane[0], arm.plane[1], arm.w2])  # arm coordinates
        self.w1 = exact.matmul(self.basis, arm.w1)  # (0, sin, cos) of axis 1 to axis 2
        self.ab = exact.cross(arm.a, arm.b)
        # the wrist's axes a, b, a x b at q4 = 0 in arm coordinates (body 3's)
        self.wrist_axes = [exact.matmul(self.basis, v) for v in (arm.a, arm.b, self.ab)]
        # axis 6 at q5 = 0 on (a, b, a x b): c = c_a a + c_ab (a x b) (c is normal to b)
        self.c_a, self.c_ab = exact.dot(arm.a, arm.c), exact.dot(self.ab, arm.c)
        self.r0 = -exact.matmul(arm.R0, arm.wrist_in_hand)  # p - c at q = 0
        self.hadamard_u = exact.dot(arm.U, arm.U) * SINGULAR_DETERMINANT**2  # |U|^2 eps^2

    # -- the factor: everything that depends on q alone (stages 2 and 3 share it) --------
    def factor(self, q: ca.SX) -> dict:
        """Everything of q (6,) [rad] the two 3 x 3 solves need: turns, the blocks of J at the wrist centre."""
        arm = self.arm
        s3 = arm.sign3
        # (cos, sin) of each turn: q2 + phi3 turns body 3 about w2 (axes 2 and 3 parallel)
        f: dict[str, Any] = {
            name: (ca.cos(angle), ca.sin(angle))
            for name, angle in (
                ("q1", q[0]),
                ("q2", q[1]),
                ("q23", q[1] + s3 * q[2]),
                ("q4", q[3]),
                ("q5", q[4]),
                ("q6", q[5]),
            )
        }
        (c2, s2), (c23, s23), (c5, s5) = f["q2"], f["q23"], f["q5"]
        Q = plane_turn(c23, s23, float(arm.U[0]), float(arm.U[1]))
        D2 = plane_turn(c2, s2, float(arm.D[0]), float(arm.D[1]))
        P = (D2[0] + Q[0], D2[1] + Q[1])
        d = [P[0] - float(arm.o12[0]), P[1] - float(arm.o12[1]), ca.SX(arm.h)]  # c - o1
        col1 = cross([float(k) for k in self.w1], d)
        g, e = col1[2], P[0] * Q[1] - P[1] * Q[0]
        W_a, W_ab = self.c_a * c5 + self.c_ab * s5, self.c_ab * c5 - self.c_a * s5
        # r on the wrist basis: Rot(b, q5) Rot(c, q6) r0
        c6, s6 = f["q6"]
        r = turn(arm.b, c5, s5, turn(arm.c, c6, s6, [ca.SX(float(x)) for x in self.r0]))
        f.update(P=P, Q=Q, D2=D2, d=d, col1=col1, W=(W_a, W_ab))
        f["r_wrist"] = [dot(arm.a, r), dot(arm.b, r), dot(self.ab, r)]
        f["r_arm"] = self.from_wrist(f, f["r_wrist"])
        # Hadamard's bound on each block: |g e| against |col1| |P| |U|, |W_ab| against 1
        norms = (col1[0] * col1[0] + col1[1] * col1[1] + col1[2] * col1[2]) * (P[0] * P[0] + P[1] * P[1])
        singular = ca.logic_or((g * e) ** 2 < self.hadamard_u * norms, ca.fabs(W_ab) < SINGULAR_DETERMINANT)
        gate = 1 + ca.if_else(singular, ca.SX(float("nan")), 0)  # 1, or NaN in every solve
        f.update(inv_g=gate / g, inv_e=gate / e, inv_W=gate / W_ab)
        return f

    # -- coordinates ------------------------------------------------------------------------
    def to_arm(self, f: dict, x: ca.SX) -> list:
        """A base-frame vector in arm coordinates."""
        c1, s1 = f["q1"]
        return [turned_dot(self.arm.w1, e, c1, s1, [x[i] for i in range(3)]) for e in self.basis]

    def to_wrist(self, f: dict, x: list) -> list:
        """Arm coordinates -> wrist coordinates: turned back by q2 + phi3 about w2, then by q4 about a."""
        c23, s23 = f["q23"]
        c4, s4 = f["q4"]
        u, v = plane_turn(c23, -s23, x[0], x[1])
        y = [u, v, x[2]]
        y_a, y_b, y_ab = (dot(k, y) for k in self.wrist_axes)
        return [y_a, *plane_turn(c4, -s4, y_b, y_ab)]

    def from_wrist(self, f: dict, x: list) -> list:
        """Wrist coordinates -> arm coordinates (to_wrist's inverse)."""
        c23, s23 = f["q23"]
        c4, s4 = f["q4"]
        y_b, y_ab = plane_turn(c4, s4, x[1], x[2])
        y = [x[0] * k_a + y_b * k_b + y_ab * k_ab for k_a, k_b, k_ab in zip(*self.wrist_axes)]
        return [*plane_turn(c23, s23, y[0], y[1]), y[2]]

    # -- the two solves -------------------------------------------------------------------
    def arm_solve(self, f: dict, b: list) -> list:
        """J11^-1 b, b in arm coordinates: x1 from the w2 row (g, 0, 0), then the plane rows of
        columns 2 and 3, w2 x P and w3 x Q = [[-P_v, -s3 Q_v], [P_u, s3 Q_u]] (s3 = +-1 the
        direction of w3), whose determinant is s3 e."""
        P, Q, col1 = f["P"], f["Q"], f["col1"]
        x1 = b[2] * f["inv_g"]
        bu, bv = b[0] - col1[0] * x1, b[1] - col1[1] * x1
        x2 = (Q[0] * bu + Q[1] * bv) * f["inv_e"]
        x3 = -self.arm.sign3 * (P[0] * bu + P[1] * bv) * f["inv_e"]
        return [x1, x2, x3]

    def arm_turn(self, x123: list) -> list:
        """J21 x_123 in arm coordinates."""
        y = x123[1] + self.arm.sign3 * x123[2]
        return [self.w1[0] * x123[0], self.w1[1] * x123[0], self.w1[2] * x123[0] + y]

    def wrist_solve(self, f: dict, y: list) -> list:
        """J22^-1 y, y in wrist coordinates."""
        W_a, _ = f["W"]
        x6 = y[2] * f["inv_W"]
        return [y[0] - W_a * x6, y[1], x6]

    # -- eqs 11 and 13 ----------------------------------------------------------------------
    def rates(self, q: ca.SX, twist: ca.SX) -> ca.SX:
        """qd = J^-1 [v; w] (eq 11)."""
        f = self.factor(q)
        v, w = self.to_arm(f, twist[:3]), self.to_arm(f, twist[3:])
        m = cross(w, f["r_arm"])
        x123 = self.arm_solve(f, [v[i] - m[i] for i in range(3)])
        turn_123 = self.arm_turn(x123)
        x456 = self.wrist_solve(f, self.to_wrist(f, [w[i] - turn_123[i] for i in range(3)]))
        return ca.vertcat(*x123, *x456)

    def accelerations(self, q: ca.SX, qd: ca.SX, accel: ca.SX) -> ca.SX:
        """qdd = J^-1 ([vdot; wdot] - Jdot qd) (eq 13), Jdot qd exact."""
        f = self.factor(q)
        s3 = self.arm.sign3
        qd1, qd2, qd4, qd5, qd6 = qd[0], qd[1], qd[3], qd[4], qd[5]
        qd23 = qd2 + s3 * qd[2]
        vdot, wdot = self.to_arm(f, accel[:3]), self.to_arm(f, accel[3:])
        # angular velocities on the wrist basis: omega_3 (joints 1-3), omega_4, omega_5, the hand's
        o = self.to_wrist(f, [self.w1[0] * qd1, self.w1[1] * qd1, self.w1[2] * qd1 + qd23])
        W_a, W_ab = f["W"]
        o4 = [o[0] + qd4, o[1], o[2]]
        o5 = [o4[0], o[1] + qd5, o[2]]
        omega = [o5[0] + qd6 * W_a, o5[1], o5[2] + qd6 * W_ab]
        # b_w of joints 4-6: omega_3 x a qd4 + omega_4 x b qd5 + omega_5 x w6 qd6
        n = cross(o5, [W_a, 0, W_ab])
        b_wrist = [qd6 * n[0] - qd5 * o[2], qd4 * o[2] + qd6 * n[1], qd5 * o4[0] - qd4 * o[1] + qd6 * n[2]]
        # a_c = vdot - wdot x r - w x (w x r)
        spin = self.from_wrist(f, cross(omega, cross(omega, f["r_wrist"])))
        wr = cross(wdot, f["r_arm"])
        # b_c: the planar arm's centripetal terms, then body 1's turn at qd1:
        # qd1^2 ((w1 . d) w1 - d) + 2 qd1 w1 x cdot (cdot the wrist centre's velocity in arm coordinates)
        D2, Q, d = f["D2"], f["Q"], f["d"]
        cdot = [-(D2[1] * qd2 + Q[1] * qd23), D2[0] * qd2 + Q[0] * qd23, 0]
        sq2, sq23, sq1 = qd2 * qd2, qd23 * qd23, qd1 * qd1
        w1 = [float(k) for k in self.w1]
        along = w1[1] * d[1] + w1[2] * d[2]
        coriolis = cross(w1, cdot)
        b_c = [sq1 * (along * w1[i] - d[i]) + 2 * qd1 * coriolis[i] for i in range(3)]
        b_c[0] = b_c[0] - (D2[0] * sq2 + Q[0] * sq23)
        b_c[1] = b_c[1] - (D2[1] * sq2 + Q[1] * sq23)
        x123 = self.arm_solve(f, [vdot[i] - wr[i] - spin[i] - b_c[i] for i in range(3)])
        # b_w of joints 1-3: qd1 (qd2 +- qd3) w1 x w2, w1 x w2 = (|w1 x w2|, 0, 0) in arm coordinates
        turn_123 = self.arm_turn(x123)
        rest = [wdot[0] - qd1 * qd23 * w1[1] - turn_123[0], wdot[1] - turn_123[1], wdot[2] - turn_123[2]]
        y = self.to_wrist(f, rest)
        return ca.vertcat(*x123, *self.wrist_solve(f, [y[i] - b_wrist[i] for i in range(3)]))
