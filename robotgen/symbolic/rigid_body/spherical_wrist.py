"""Closed-form inverse kinematics of six-revolute arms with a spherical wrist: the elbow
manipulators of the PUMA 560 family (Paul, Shimano and Mayer 1981; Lee and Ziegler 1984),
solved from the arm's geometry by the Paden-Kahan subproblems (Murray, Li and Sastry 1994,
§3.3) rather than from one DH table.

Geometry at q = 0, in base coordinates: joint i turns about the line through o_i along the
unit w_i, and the hand is at G0. Since frame(i) = frame(parent) @ origin @ motion, the hand
at q is e_1(q_1) ... e_6(q_6) G0, e_i the turn by q_i about line i (product of
exponentials, Brockett 1984).

The family, decided at build time (`spherical_wrist_arm`):
- six revolute joints, one chain from the base to the hand;
- axes 2 and 3 parallel (two distinct lines), axis 1 not parallel to them; axis 1 need not
  pass through the base origin, meet axis 2 or be perpendicular to it. The wrist centre's
  distance along w2 from axis 2 (the PUMA's d3 = 0.15005 m) and its offset from axis 3's
  normal plane (a3 = 0.0203 m) are any;
- axes 4, 5, 6 meet in one point, the wrist centre c0, with axis 5 perpendicular to axes 4
  and 6 (4 and 6 at any angle to each other).
Each condition holds to FAMILY_TOLERANCE (1e-9 rad, or m times the arm's size); the solution
is that of the exact geometry, so on an arm whose file writes pi/2 to 11 digits (rotation
entries of 4.9e-12, which snapping keeps) it is within about 1e-11 of the model's own.

Solving (R_d, p_d), hand at G_d:
1. The wrist does not move c0, so e_1 e_2 e_3 c0 = G_d G0^-1 c0: the wrist centre p_c.
2. Joints 2 and 3 turn about lines parallel to w2 and keep w2 . (x - o2) = h for the
   wrist centre: theta1 turns p_c back onto that plane (subproblem: a rotation taking a
   point to a plane), two solutions (shoulder left, right).
3. theta3 puts the wrist centre at its distance from o2 (subproblem 3), two solutions
   (elbow up, down); theta2 then turns it onto the target (subproblem 1), one.
4. The wrist's rotation R_w = R_123^T R_d R0^T = Rot(a, q4) Rot(b, q5) Rot(c, q6), a, b, c
   its axes: q4 from R_w c (subproblem 2), two solutions (wrist flip); then q5 from
   Rot(a, -q4) R_w c = Rot(b, q5) c and q6 from R_w^T Rot(a, q4) b = Rot(c, -q6) b, one each.
   2 x 2 x 2 = 8.

`solve` picks a branch by the current angles q_near: of each pair the candidate nearer
q_near's (in cos of the difference), the shoulder by q1, the elbow by q3, the wrist flip by
q4 (the flip turns q4 by pi, so q4 tells the two apart even where q5's two values meet).
It writes every angle as q_near's plus the difference wrapped to [-pi, pi] (IEEE remainder
by 2 pi; the 2 pi multiple nearest q_near: a PUMA's q6 ranges over +-266 degrees), and the
branches by the sign of a wrapped difference (the wrist flip: the difference wrapped to
[-pi/2, pi/2], remainder by pi): straight-line code, no sin or cos of q_near. Singularities: a
target out of reach gives NaN in all six angles (a checked step then returns status 2);
a wrist centre on axis 1, on axis 2, or the wrist at q5's singular value keep q1, q2, q4
at q_near (q6 then takes the wrist's whole turn about axis 4)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robotgen.model.chain import REVOLUTE, KinematicTree
from robotgen.model.snap import snap_tree
from robotgen.numeric import exact
from robotgen.symbolic.rigid_body.axis_turns import dot, turn, turned_dot

FAMILY_TOLERANCE = 1e-9  # the family's conditions, and the solve's singular neighbourhoods

# A square root of a negative number within this fraction of its scale is rounding at the
# edge of the workspace (the arm stretched out), not a target out of reach.
REACH_TOLERANCE = 1e-12
# The wrist is taken as singular where |sin| of q5's distance from its singular value is
# below this: the regular formulas' rounding (1e-16 / that) and the orientation error of
# holding q4 (about that) are then both below it.
WRIST_SINGULAR = 1e-8
TURN, HALF_TURN = 2 * math.pi, math.pi  # remainder(x, TURN): x wrapped to [-pi, pi]


@dataclass(frozen=True, eq=False)
class SphericalWristArm:
    """The build-time constants of one arm of the family (base coordinates at q = 0)."""

    wrist_in_hand: np.ndarray  # c0 in the hand frame at q = 0
    w1: np.ndarray
    o1: np.ndarray  # the point of axis 1 nearest axis 2
    w2: np.ndarray  # axis 2's direction; axis 3's is sign3 * w2
    sign3: float
    h: float  # w2 . (c0 - o2), o2 the point of axis 2 nearest axis 1
    plane: np.ndarray  # 2 x 3: rows e_u, e_v spanning the plane normal to w2, e_u x e_v = w2
    o12: np.ndarray  # (e_u, e_v) . (o1 - o2)
    D: np.ndarray  # (e_u, e_v) . (o3 - o2)
    U: np.ndarray  # (e_u, e_v) . (c0 - o3)
    a: np.ndarray  # the wrist's axes 4, 5, 6
    b: np.ndarray
    c: np.ndarray
    R0: np.ndarray  # the hand's orientation at q = 0
    scale: float  # the arm's size [m], at least 1, for the length tolerances

    # -- the run-time graphs --------------------------------------------------------------
    def solve(self, R_d: ca.SX, p_d: ca.SX, q_near: ca.SX) -> ca.SX:
        """The solution nearest q_near (shoulder by q1, elbow by q3, wrist flip by q4), every
        angle within pi of q_near's."""
        return self._solve(R_d, p_d, q_near, None)

    def solutions(self, R_d: ca.SX, p_d: ca.SX) -> list[ca.SX]:
        """All eight, angles in (-pi, pi], in the order of (shoulder, elbow, wrist) signs
        (+++, ++-, +-+, ..., ---)."""
        return [
            self._solve(R_d, p_d, ca.SX.zeros(6), (s1, s3, s5))
            for s1 in (1.0, -1.0)
            for s3 in (1.0, -1.0)
            for s5 in (1.0, -1.0)
        ]

    def _solve(self, R_d: ca.SX, p_d: ca.SX, qn: ca.SX, signs: tuple[float, float, float] | None) -> ca.SX:
        tol = FAMILY_TOLERANCE * self.scale
        nan = ca.SX(float("nan"))
        # 1. the wrist centre
        p_c = [p_d[i] + dot(self.wrist_in_hand, [R_d[i, k] for k in range(3)]) for i in range(3)]
        x = [p_c[i] - self.o1[i] for i in range(3)]
        # 2. theta1: (Rot(w1, q1) w2) . x = h (o1 - o2 is normal to w2), i.e.
        # A cos q1 + B sin q1 = E: q1 = phi +- beta, phi = atan2(B, A), beta = atan2(root1, E) in [0, pi]
        w1, w2 = self.w1, self.w2
        cw = exact.dot(w1, w2)
        A = dot(exact.add(w2, (-cw, w1)), x)
        B = dot(exact.cross(w1, w2), x)
        E = self.h - cw * dot(w1, x) if cw else ca.SX(self.h)
        r2 = A * A + B * B
        root1_sq = r2 - E * E
        phi, beta = ca.atan2(B, A), ca.atan2(ca.sqrt(ca.fmax(root1_sq, 0)), E)
        if signs:
            d1 = ca.remainder(phi + signs[0] * beta, TURN)
        else:
            # the candidate nearer qn is phi + beta where sin(phi - qn) < 0, i.e. where
            # delta = qn - phi (wrapped) > 0; q1 - qn = (+-beta - delta) wrapped
            delta = ca.remainder(qn[0] - phi, TURN)
            d1 = ca.remainder(ca.copysign(beta, delta) - delta, TURN)
        # out of reach (shoulder): NaN in q1, hence in every angle after it
        q1 = qn[0] + ca.if_else(r2 < tol * tol, 0, d1) + ca.if_else(root1_sq < -REACH_TOLERANCE * r2, nan, 0)
        c1, s1 = ca.cos(q1), ca.sin(q1)
        # 3. the wrist centre turned back by q1, in plane coordinates about o2:
        # e . Rot(w1, -q1) x = (Rot(w1, q1) e) . x
        P = [turned_dot(w1, self.plane[k], c1, s1, x) + self.o12[k] for k in range(2)]
        dd = P[0] * P[0] + P[1] * P[1]
        # theta3 (subproblem 3): |D + Rot(phi3) U|^2 = dd, phi3 = sign3 q3 about w2;
        # cos(phi3 - psi0) = k3, psi0 the angle from U to D: phi3 = psi0 +- beta3
        nD, nU = exact.norm(self.D), exact.norm(self.U)
        kappa = 1 / (2 * nD * nU)
        psi0 = math.atan2(self.U[0] * self.D[1] - self.U[1] * self.D[0], self.D[0] * self.U[0] + self.D[1] * self.U[1])
        k3 = dd * kappa - (nD * nD + nU * nU) * kappa
        root3_sq = 1 - k3 * k3
        elbow_out = root3_sq < -REACH_TOLERANCE  # out of reach (elbow): NaN in every angle
        flag3 = ca.if_else(elbow_out, nan, 0)
        root3 = ca.sqrt(ca.fmax(root3_sq, 0) + flag3)
        beta3 = ca.atan2(root3, k3)
        if signs:
            d3 = ca.remainder(self.sign3 * (psi0 + signs[1] * beta3), TURN)
            sroot3 = signs[1] * root3
        else:
            # q3 = sign3 psi0 + sign3 sigma beta3; the nearer qn3 has sign3 sigma = sign(delta3),
            # delta3 = qn3 - sign3 psi0 (wrapped)
            delta3 = ca.remainder(qn[2] - self.sign3 * psi0, TURN)
            d3 = ca.remainder(ca.copysign(beta3, delta3) - delta3, TURN)
            sroot3 = ca.copysign(root3, self.sign3 * delta3)  # sigma root3
        q3 = qn[2] + d3
        # theta2 (subproblem 1): Rot(w2, q2) X = P, X = D + Rot(phi3) U; in D's frame
        # X = |U| (|D| / |U| + k3, sigma root3) (D . Rot(phi3) U = |D| |U| k3)
        theta_X = ca.atan2(sroot3, nD / nU + k3) + math.atan2(self.D[1], self.D[0])
        d2 = ca.remainder(ca.atan2(P[1], P[0]) - theta_X - qn[1], TURN)
        held = ca.logic_and(dd < tol * tol, ca.logic_not(elbow_out))  # the wrist centre on axis 2
        q2 = qn[1] + ca.if_else(held, 0, d2)
        q23 = q2 + self.sign3 * q3  # about w2
        c23, s23 = ca.cos(q23), ca.sin(q23)
        # 4. the wrist: R_w c = R_123^T R_d R0^T c = alpha a + beta b + gamma (a x b),
        # R_123 = Rot(w1, q1) Rot(w2, q2 + phi3), turned back from R_d R0^T c
        a, b, c = self.a, self.b, self.c
        u = turn(w2, c23, -s23, turn(w1, c1, -s1, _columns(R_d, exact.matmul(self.R0.T, c))))
        alpha, beta, gamma = (dot(k, u) for k in (a, b, exact.cross(a, b)))
        wrist = beta * beta + gamma * gamma < WRIST_SINGULAR**2  # rho = |sin(q5 - its singular value)|
        if signs:
            d4 = ca.remainder(ca.atan2(-signs[2] * beta, signs[2] * gamma), TURN)
        else:
            # q4 = atan2(-s beta, s gamma), s = +-1 the wrist flip, which turns q4 by pi: the
            # nearer qn4 is qn4 + (atan2(-beta, gamma) - qn4) wrapped to [-pi/2, pi/2]
            d4 = ca.remainder(ca.atan2(dot(-b, u), gamma) - qn[3], HALF_TURN)
        q4 = qn[3] + ca.if_else(wrist, 0, d4)  # the singular wrist keeps qn4
        c4, s4 = ca.cos(q4), ca.sin(q4)
        # Rot(a, -q4) R_w c = Rot(b, q5) c = Rot(b, q5 + theta_c) a: q5 + theta_c from its
        # components along a (alpha) and b x a (s4 beta - c4 gamma)
        theta_c = math.atan2(exact.dot(exact.cross(b, a), c), exact.dot(a, c))
        q5 = qn[4] + ca.remainder(ca.atan2(s4 * beta - c4 * gamma, alpha) - theta_c - qn[4], TURN)
        # R_w^T Rot(a, q4) b = Rot(c, -q6) b = cos q6 b + sin q6 (b x c) (b normal to c), also at the
        # singular wrist, where q6 then takes the turn that q4 keeps: its components are
        # (R_d R0^T y) . z, y = b and b x c, z = R_123 Rot(a, q4) b (axis 5)
        z = turn(w1, c1, s1, turn(w2, c23, s23, turn(a, c4, s4, [ca.SX(float(v)) for v in b])))
        C6, S6 = (_dot3(_columns(R_d, exact.matmul(self.R0.T, y)), z) for y in (b, exact.cross(b, c)))
        q6 = qn[5] + ca.remainder(ca.atan2(S6, C6) - qn[5], TURN)
        return ca.vertcat(q1 + flag3, q2, q3, q4, q5, q6)


def _columns(R: ca.SX, k: np.ndarray) -> list:
    """R k for a constant k, skipping its zeros."""
    return [dot(k, [R[i, j] for j in range(3)]) for i in range(3)]


def _dot3(u: list, v: list) -> ca.SX:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


# -- the family, at build time ------------------------------------------------------------
def spherical_wrist_arm(tree: KinematicTree) -> SphericalWristArm | None:
    """The arm's closed-form constants when it belongs to the family (module docstring),
    else None."""
    tree = snap_tree(tree)
    if tree.coupling is not None or tree.nq != 6 or tree.support(tree.tip) != list(range(6)):
        return None
    if any(j.type != REVOLUTE for j in tree.joints):
        return None
    frames: list[np.ndarray] = []
    for j in tree.joints:
        frames.append(exact.matmul(frames[j.parent] if j.parent >= 0 else np.eye(4), j.origin))
    w = [exact.unit(exact.matmul(T[:3, :3], j.axis)) for T, j in zip(frames, tree.joints)]
    o = [T[:3, 3] for T in frames]
    G0 = exact.matmul(frames[5], tree.tool)
    scale = max(1.0, *(exact.norm(p) for p in o), exact.norm(G0[:3, 3]))
    tol, length_tol = FAMILY_TOLERANCE, FAMILY_TOLERANCE * scale
    w1, w2, w3, a, b, c = w
    if exact.norm(exact.cross(w2, w3)) > tol or exact.norm(exact.cross(w1, w2)) <= tol:
        return None
    if abs(exact.dot(a, b)) > tol or abs(exact.dot(b, c)) > tol:
        return None
    # the wrist centre: where axes 4 and 5 meet, on axis 6
    f4, f5 = _feet(o[3], a, o[4], b)
    c0 = f5
    if exact.norm(exact.add(f4, (-1.0, f5))) > length_tol:
        return None
    if exact.norm(exact.cross(exact.add(c0, (-1.0, o[5])), c)) > length_tol:
        return None
    o1, o2 = _feet(o[0], w1, o[1], w2)
    e_v = exact.unit(exact.add(w1, (-exact.dot(w1, w2), w2)))
    plane = np.array([exact.cross(e_v, w2), e_v])
    D = exact.matmul(plane, exact.add(o[2], (-1.0, o2)))
    U = exact.matmul(plane, exact.add(c0, (-1.0, o[2])))
    if exact.norm(D) <= length_tol or exact.norm(U) <= length_tol:
        return None  # axes 2 and 3 one line, or the wrist centre on axis 3: no elbow
    R0, p0 = G0[:3, :3], G0[:3, 3]
    return SphericalWristArm(
        wrist_in_hand=exact.matmul(R0.T, exact.add(c0, (-1.0, p0))),
        w1=w1,
        o1=o1,
        w2=w2,
        sign3=1.0 if exact.dot(w2, w3) > 0 else -1.0,
        h=exact.dot(w2, exact.add(c0, (-1.0, o2))),
        plane=plane,
        o12=exact.matmul(plane, exact.add(o1, (-1.0, o2))),
        D=D,
        U=U,
        a=a,
        b=b,
        c=c,
        R0=R0,
        scale=scale,
    )


def _feet(p1: np.ndarray, u1: np.ndarray, p2: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest points of two lines that are not parallel (p + t u, unit u)."""
    d = exact.add(p1, (-1.0, p2))
    cu, a1, a2 = exact.dot(u1, u2), exact.dot(u1, d), exact.dot(u2, d)
    den = 1 - cu * cu
    t, s = (cu * a2 - a1) / den, (a2 - cu * a1) / den
    return exact.add(p1, (t, u1)), exact.add(p2, (s, u2))
