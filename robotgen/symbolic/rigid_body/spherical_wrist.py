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
Each condition holds to SNAP_TOLERANCE (rad, or m times the arm's size), which accepts the
exact geometry that snapping leaves; the solution is that of the exact geometry.

Solving (R_d, p_d), hand at G_d:
1. The wrist does not move c0, so e_1 e_2 e_3 c0 = G_d G0^-1 c0: the wrist centre p_c.
2. Joints 2 and 3 turn about lines parallel to w2 and keep w2 . (x - o2) = h for the
   wrist centre: theta1 turns p_c back onto that plane (subproblem: a rotation taking a
   point to a plane), two solutions (shoulder left, right).
3. theta3 puts the wrist centre at its distance from o2 (subproblem 3), two solutions
   (elbow up, down); theta2 then turns it onto the target (subproblem 1), one.
4. The wrist's rotation R_w = R_123^T R_d R0^T = Rot(a, q4) Rot(b, q5) Rot(c, q6), a, b, c
   its axes: q4, q5 from R_w c (subproblem 2), q6 from R_w^T a (subproblem 2 of the inverse
   rotation), two solutions (wrist flip). 2 x 2 x 2 = 8.

`solve` picks a branch by the current angles q_near: of each pair the candidate nearer
q_near's (in cos of the difference), the shoulder by q1, the elbow by q3, the wrist flip by
q4 (the flip turns q4 by pi, so q4 tells the two apart even where q5's two values meet).
It writes every angle as q_near's plus the difference wrapped to (-pi, pi] (the 2 pi
multiple nearest q_near: a PUMA's q6 ranges over +-266 degrees), from one atan2 each of
the solution's (cos, sin) turned back by q_near: straight-line code, the choices by
selection. Singularities: a
target out of reach gives NaN in all six angles (a checked step then returns status 2);
a wrist centre on axis 1, on axis 2, or the wrist at q5's singular value keep q1, q2, q4
at q_near (q6 then takes the wrist's whole turn about axis 4)."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from robotgen.model.chain import REVOLUTE, KinematicTree
from robotgen.model.snap import SNAP_TOLERANCE, snap_tree
from robotgen.numeric import exact

# A square root of a negative number within this fraction of its scale is rounding at the
# edge of the workspace (the arm stretched out), not a target out of reach.
REACH_TOLERANCE = 1e-12
# The wrist is taken as singular where |sin| of q5's distance from its singular value is
# below this: the regular formulas' rounding (1e-16 / that) and the orientation error of
# holding q4 (about that) are then both below it.
WRIST_SINGULAR = 1e-8


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
        return [self._solve(R_d, p_d, ca.SX.zeros(6), (s1, s3, s5))
                for s1 in (1.0, -1.0) for s3 in (1.0, -1.0) for s5 in (1.0, -1.0)]

    def _solve(self, R_d: ca.SX, p_d: ca.SX, qn: ca.SX, signs: tuple[float, float, float] | None) -> ca.SX:
        cq, sq = [ca.cos(qn[i]) for i in range(6)], [ca.sin(qn[i]) for i in range(6)]
        tol = SNAP_TOLERANCE * self.scale
        # 1. the wrist centre
        p_c = [p_d[i] + _dot(self.wrist_in_hand, [R_d[i, k] for k in range(3)]) for i in range(3)]
        x = [p_c[i] - self.o1[i] for i in range(3)]
        # 2. theta1: (Rot(w1, q1) w2) . x = h (o1 - o2 is normal to w2), i.e.
        # A cos q1 + B sin q1 = E; q1 = atan2(B, A) +- atan2(s1, E), s1 = sqrt(A^2 + B^2 - E^2)
        w1, w2 = self.w1, self.w2
        cw = exact.dot(w1, w2)
        A = _dot(exact.add(w2, (-cw, w1)), x)
        B = _dot(exact.cross(w1, w2), x)
        E = self.h - cw * _dot(w1, x) if cw else ca.SX(self.h)
        r2 = A * A + B * B
        root1_sq = r2 - E * E
        root1 = ca.sqrt(ca.fmax(root1_sq, 0))
        # q1 = phi +- beta, phi = atan2(B, A), beta = atan2(root1, E) in [0, pi]; the candidate
        # nearer q_near: cos(phi + beta - qn) - cos(phi - beta - qn) = -2 sin(phi - qn) sin(beta),
        # sin(phi - qn) = S / r. q1 - qn in one atan2 of (C, S) = r (cos, sin)(phi - qn) turned by beta
        C, S = A * cq[0] + B * sq[0], B * cq[0] - A * sq[0]
        sign1 = signs[0] if signs else _sign(S < 0)
        root1 = sign1 * root1
        d1 = ca.if_else(r2 < tol * tol, 0, ca.atan2(E * S + root1 * C, E * C - root1 * S))
        q1 = qn[0] + d1
        c1, s1 = ca.cos(q1), ca.sin(q1)
        # 3. the wrist centre turned back by q1, in plane coordinates about o2:
        # e . Rot(w1, -q1) x = (Rot(w1, q1) e) . x
        P = [_turned_dot(w1, self.plane[k], c1, s1, x) + self.o12[k] for k in range(2)]
        dd = P[0] * P[0] + P[1] * P[1]
        # theta3 (subproblem 3): |D + Rot(phi3) U|^2 = dd, phi3 = sign3 q3 about w2;
        # cos(phi3 - psi0) = k, psi0 the angle from U to D
        nD, nU = exact.norm(self.D), exact.norm(self.U)
        kappa = 1 / (2 * nD * nU)
        lam = (nD * nD + nU * nU) * kappa
        cpsi = (self.D[0] * self.U[0] + self.D[1] * self.U[1]) * kappa * 2
        spsi = (self.U[0] * self.D[1] - self.U[1] * self.D[0]) * kappa * 2
        k3 = dd * kappa - lam
        root3_sq = 1 - k3 * k3
        root3 = ca.sqrt(ca.fmax(root3_sq, 0))
        # phi3 = psi0 +- beta, beta = atan2(root3, k3); q3 = sign3 phi3 nearer q_near as for q1:
        # the + candidate when sign3 sin(sign3 psi0 - qn3) < 0
        sign3 = signs[1] if signs else _sign(spsi * cq[2] - self.sign3 * cpsi * sq[2] < 0)
        root3 = sign3 * root3
        cphi, sphi = cpsi * k3 - spsi * root3, spsi * k3 + cpsi * root3
        q3 = qn[2] + _from(cphi, self.sign3 * sphi, cq[2], sq[2])
        # theta2 (subproblem 1): Rot(w2, q2) X = P, X = D + Rot(phi3) U
        Xu = self.D[0] + (cphi * self.U[0] - sphi * self.U[1])
        Xv = self.D[1] + (sphi * self.U[0] + cphi * self.U[1])
        d2 = ca.if_else(dd < tol * tol, 0, _from(Xu * P[0] + Xv * P[1], Xu * P[1] - Xv * P[0], cq[1], sq[1]))
        q2 = qn[1] + d2
        q23 = q2 + self.sign3 * q3  # about w2
        c23, s23 = ca.cos(q23), ca.sin(q23)
        # 4. the wrist: entries x^T R_w y = (R_123 x) . (R_d R0^T y), R_123 = Rot(w1, q1) Rot(w2, q2 + phi3)
        a, b, c = self.a, self.b, self.c
        ab, cb = exact.cross(a, b), exact.cross(c, b)
        left = {name: _turned(w1, c1, s1, _turned(w2, c23, s23, list(v))) for name, v in (("a", a), ("b", b),
                                                                                         ("ab", ab))}
        right = {name: [_dot(exact.matmul(self.R0.T, y), [R_d[i, k] for k in range(3)]) for i in range(3)]
                 for name, y in (("c", c), ("b", b), ("cb", cb))}

        def entry(u: str, v: str) -> ca.SX:
            return left[u][0] * right[v][0] + left[u][1] * right[v][1] + left[u][2] * right[v][2]

        # R_w c = alpha a + beta b + gamma (a x b); R_w^T a . b = nu, R_w^T a . (c x b) = mu
        alpha, beta, gamma = entry("a", "c"), entry("b", "c"), entry("ab", "c")
        nu, mu = entry("a", "b"), entry("a", "cb")
        rho2 = beta * beta + gamma * gamma  # 1 - alpha^2, by its small terms
        rho = ca.sqrt(rho2)
        # theta_a turns c onto a about b (constant): q5 = theta_a + atan2(-s rho, alpha)
        cos_a, sin_a = exact.dot(c, a), exact.dot(b, exact.cross(c, a))
        # q4 = atan2(-s beta, s gamma), s = +-1 the wrist flip (subproblem 2 on R_w c, below),
        # turned back by qn4: atan2(s Y4, s X4); the flip turns q4 by pi, so the branch whose
        # q4 is nearer q_near's is the one with s X4 > 0 (held through the singular wrist)
        X4, Y4 = gamma * cq[3] - beta * sq[3], -(beta * cq[3] + gamma * sq[3])
        if signs:
            sign5, d4 = signs[2], ca.atan2(signs[2] * Y4, signs[2] * X4)
        else:
            sign5 = _sign(X4 > 0)
            d4 = ca.atan2(sign5 * Y4, ca.fabs(X4))
        wrist = rho < WRIST_SINGULAR
        d4 = ca.if_else(wrist, 0, d4)
        q5 = qn[4] + _from(cos_a * alpha + sign5 * (sin_a * rho), sin_a * alpha - sign5 * (cos_a * rho), cq[4], sq[4])
        # at the singular wrist R_w = Rot(a, q4 + t q6) Rot(b, q5), t = sign(alpha) (Rot(b, q5) c = t a):
        # with q4 held, q6 = t (phi - qn4), phi the turn of b onto R_w b about a; alpha stands
        # for t (they differ by rho^2 / 2 there)
        C6, S6 = entry("b", "b"), entry("ab", "b")
        held = _from(C6 * cq[3] + S6 * sq[3], alpha * (S6 * cq[3] - C6 * sq[3]), cq[5], sq[5])
        d6 = ca.if_else(wrist, held, _from(-sign5 * mu, -sign5 * nu, cq[5], sq[5]))
        # out of reach: NaN in every angle
        unreachable = ca.logic_or(root1_sq < -REACH_TOLERANCE * r2, root3_sq < -REACH_TOLERANCE)
        nan = ca.if_else(unreachable, ca.SX(float("nan")), 0)
        return ca.vertcat(q1, q2, q3, qn[3] + d4, q5, qn[5] + d6) + nan


def _sign(condition: ca.SX) -> ca.SX:
    """+1 where condition holds, else -1."""
    return 2 * condition - 1


def _dot(constant, v) -> ca.SX:
    """constant . v, skipping the constant's zeros."""
    terms = [float(k) * v[i] for i, k in enumerate(constant) if k]
    return sum(terms[1:], terms[0]) if terms else ca.SX(0)


def _from(X: ca.SX, Y: ca.SX, cq: ca.SX, sq: ca.SX) -> ca.SX:
    """atan2(Y, X) - q wrapped to (-pi, pi], from (cos q, sin q)."""
    return ca.atan2(Y * cq - X * sq, X * cq + Y * sq)


def _turned(w: np.ndarray, c: ca.SX, s: ca.SX, v: list) -> list:
    """Rot(w, q) v (Rodrigues), (cos q, sin q) = (c, s), constant unit w."""
    w = [float(x) for x in w]
    k = _dot(w, v)
    cross = [w[1] * v[2] - w[2] * v[1], w[2] * v[0] - w[0] * v[2], w[0] * v[1] - w[1] * v[0]]
    return [w[i] * k + c * (v[i] - w[i] * k) + s * cross[i] for i in range(3)]


def _turned_dot(w: np.ndarray, e: np.ndarray, c: ca.SX, s: ca.SX, x: list) -> ca.SX:
    """(Rot(w, q) e) . x for constants w, e."""
    we = exact.dot(w, e)
    return we * _dot(w, x) + c * _dot(exact.add(e, (-we, w)), x) + s * _dot(exact.cross(w, e), x)


# -- the family, at build time ------------------------------------------------------------
def spherical_wrist_arm(tree: KinematicTree) -> SphericalWristArm | None:
    """The arm's closed-form constants when it belongs to the family (module docstring),
    else None."""
    tree = snap_tree(tree)
    if tree.nq != 6 or tree.support(tree.tip) != list(range(6)):
        return None
    if any(j.type != REVOLUTE for j in tree.joints):
        return None
    frames = []
    for j in tree.joints:
        frames.append(exact.matmul(frames[j.parent] if j.parent >= 0 else np.eye(4), j.origin))
    w = [exact.unit(exact.matmul(T[:3, :3], j.axis)) for T, j in zip(frames, tree.joints)]
    o = [T[:3, 3] for T in frames]
    G0 = exact.matmul(frames[5], tree.tool)
    scale = max(1.0, *(exact.norm(p) for p in o), exact.norm(G0[:3, 3]))
    tol, length_tol = SNAP_TOLERANCE, SNAP_TOLERANCE * scale
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
        wrist_in_hand=exact.matmul(R0.T, exact.add(c0, (-1.0, p0))), w1=w1, o1=o1, w2=w2,
        sign3=1.0 if exact.dot(w2, w3) > 0 else -1.0, h=exact.dot(w2, exact.add(c0, (-1.0, o2))), plane=plane,
        o12=exact.matmul(plane, exact.add(o1, (-1.0, o2))), D=D, U=U, a=a, b=b, c=c, R0=R0, scale=scale)


def _feet(p1: np.ndarray, u1: np.ndarray, p2: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest points of two lines that are not parallel (p + t u, unit u)."""
    d = exact.add(p1, (-1.0, p2))
    cu, a1, a2 = exact.dot(u1, u2), exact.dot(u1, d), exact.dot(u2, d)
    den = 1 - cu * cu
    t, s = (cu * a2 - a1) / den, (a2 - cu * a1) / den
    return exact.add(p1, (t, u1)), exact.add(p2, (s, u2))
