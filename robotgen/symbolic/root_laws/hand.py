"""The hand of a 6-joint chain in Lee and Lee's terms (1983, §2), as CasADi graphs: its pose
(eq 1), roll-pitch-yaw (eq 2), twist (eq 8), the Euler-rate map (eqs 6-7), the resolved
motion maps from hand to joint rates and accelerations (eqs 11, 13: for an arm with a
spherical wrist two 3 x 3 solves at the wrist centre, rigid_body/inverse_jacobian.py; a 6 x 6
solve otherwise), inverse kinematics (in closed form for an arm with a spherical wrist,
rigid_body/spherical_wrist.py; Newton steps otherwise), and the Newton-Euler torques (Luh,
Walker, Paul 1980).

Every quantity is a CasADi Function of the chain's joint state, built once from the chain's
graphs (robotgen.symbolic.rigid_body.chain) and called on whatever joint values a law needs
(measured or resolved): a call on SX arguments inlines the graph."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from robotgen.model.chain import KinematicTree
from robotgen.model.laws.hand import START_ANGLE, START_DISTANCE
from robotgen.numeric import exact
from robotgen.symbolic.kernel import Kernel, make_kernel
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve_matrix
from robotgen.symbolic.rigid_body.inverse_jacobian import WristCentreJacobian
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rate_map, rpy_rates
from robotgen.symbolic.rigid_body.spherical_wrist import SphericalWristArm, spherical_wrist_arm
from robotgen.symbolic.root_laws.law import StartCheck
from robotgen.symbolic.root_laws.resolved_rate.resolution import DampedResolver

N = 6
# A 6 x 6 solve refuses a Jacobian whose QR factor R has a pivot below this fraction of its
# largest (a condition number of about 1e6 or more): the answer would be torques of 1e6 x the
# command and more, so it is NaN instead, which a checked step turns into status 2 with zero
# outputs (docs/c-api.md). Near singular is where resolved motion has no sane answer.
SINGULAR_PIVOT = 1e-6


def checked_solve(J: ca.SX, b: ca.SX) -> ca.SX:
    """J^-1 b by Householder QR of J^T (J = R^T Q^T, so J^-1 b = Q R^-T b); NaN when J is
    singular to SINGULAR_PIVOT."""
    resolver = DampedResolver(J, None)
    pivots = [ca.fabs(resolver.qr.R[k][k]) for k in range(J.shape[0])]
    smallest, largest = pivots[0], pivots[0]
    for pivot in pivots[1:]:
        smallest, largest = ca.fmin(smallest, pivot), ca.fmax(largest, pivot)
    return resolver.pinv_times(b) * ca.if_else(smallest > SINGULAR_PIVOT * largest, 1, ca.SX(float("nan")))


def pose_rows(pose: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(R, p) of a 4x4 homogeneous transform given as 16 entries, row-major."""
    R = ca.vertcat(*[ca.horzcat(*[pose[4 * i + k] for k in range(3)]) for i in range(3)])
    return R, ca.vertcat(*[pose[4 * i + 3] for i in range(3)])


def orientation_error(R_d: ca.SX, R: ca.SX) -> ca.SX:
    """(n x n_d + s x s_d + a x a_d) / 2 (Luh, Walker, Paul 1980): the vector part of
    R_d R^T, sin(angle) times the axis that turns R into R_d (base coordinates)."""
    E = R_d @ R.T
    return 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])


def rotation_angle(R_d: ca.SX, R: ca.SX) -> ca.SX:
    """The angle in [0, pi] of the rotation R_d R^T, from its sine (the norm of the vector part
    of orientation_error) and its cosine ((trace - 1) / 2): accurate near 0 and near pi."""
    E = R_d @ R.T
    return ca.atan2(ca.norm_2(orientation_error(R_d, R)), 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1))


def wrap(angle: ca.SX) -> ca.SX:
    """An angle difference in (-pi, pi]."""
    return ca.atan2(ca.sin(angle), ca.cos(angle))


class Hand:
    """The hand frame of ``tree`` (its tip frame times ``tool``) and what the laws need."""

    def __init__(self, tree: KinematicTree, tool: np.ndarray):
        tree = dataclasses.replace(tree, tool=exact.matmul(tree.tool, tool))
        self.tree = tree
        # the PUMA 560 family's inverse kinematics in closed form; None: Newton steps
        self.closed_form: SphericalWristArm | None = spherical_wrist_arm(tree)
        # ... and its Jacobian at the wrist centre, block lower triangular (eqs 11, 13)
        self.wrist_centre = WristCentreJacobian(self.closed_form) if self.closed_form else None
        s = Symbols.make(tree.nq)
        self.sym = s
        g = ChainGraphs(tree, s)
        fk = g.fk()
        self._pose = ca.Function("hand_pose", [s.q], [fk[:3, :3], fk[:3, 3]])
        self._jacobian = ca.Function("hand_jacobian", [s.q], [g.jacobian()])
        self._bias = ca.Function("hand_bias", [s.q, s.qd], [g.jacobian_dot_qd()])
        self._torque = ca.Function("newton_euler", [s.q, s.qd, s.qdd], [g.inverse_dynamics()])
        self._accel = ca.Function("joint_accelerations", [s.q, s.qd, s.tau], [g.forward_dynamics()])
        self._mass = ca.Function("mass", [s.q], [g.mass()])
        # d tau/d(q, qd): the chain's derivative algorithm (robotgen.symbolic.rigid_body.chain)
        self._torque_derivatives = ca.Function(
            "newton_euler_derivatives", [s.q, s.qd, s.qdd], [ca.horzcat(*g.inverse_dynamics_derivatives())]
        )

    # -- kinematics (§2) ---------------------------------------------------------------
    def pose(self, q: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(R, p) of the hand in the base frame (eq 1)."""
        R, p = self._pose(q)
        return R, p

    def jacobian(self, q: ca.SX) -> ca.SX:
        """6 x 6: [v; Omega] = J qd (eqs 8-9)."""
        return self._jacobian(q)

    def bias(self, q: ca.SX, qd: ca.SX) -> ca.SX:
        """Jdot qd: the hand acceleration at qdd = 0 (eq 10), from Newton-Euler's forward pass."""
        return self._bias(q, qd)

    def state(self, q: ca.SX, qd: ca.SX) -> ca.SX:
        """x = (p, Phi, v, Omega) (eq 20)."""
        R, p = self.pose(q)
        return ca.vertcat(p, rpy_of(R), self.jacobian(q) @ qd)

    # -- resolved motion (eqs 11, 13) --------------------------------------------------
    def joint_rates(self, q: ca.SX, twist: ca.SX) -> ca.SX:
        """qd = J^-1 [v; Omega] (eq 11), by a solve (NaN at or near a singular J): two 3 x 3
        solves at the wrist centre for an arm with a spherical wrist, else checked_solve."""
        if self.wrist_centre is not None:
            return self.wrist_centre.rates(q, twist)
        return checked_solve(self.jacobian(q), twist)

    def joint_accelerations(self, q: ca.SX, qd: ca.SX, accel: ca.SX) -> ca.SX:
        """qdd = J^-1 ([vdot; Omegadot] - Jdot qd) (eq 13), by a solve (NaN at or near a
        singular J), with joint_rates' factor."""
        if self.wrist_centre is not None:
            return self.wrist_centre.accelerations(q, qd, accel)
        return checked_solve(self.jacobian(q), accel - self.bias(q, qd))

    def inverse_kinematics(self, R_d: ca.SX, p_d: ca.SX, q0: ca.SX, iterations: int) -> ca.SX:
        """q with the hand at (R_d, p_d). For an arm with a spherical wrist, in closed form: the
        solution nearest q0, each angle within pi of q0's (NaN out of reach). Otherwise
        ``iterations`` Newton steps q <- q + J^-1 [p_d - p; e_o] from q0 (a prediction close to
        the answer: the fixed count is then enough, and the graph stays straight-line code)."""
        if self.closed_form is not None:
            return self.closed_form.solve(R_d, p_d, q0)
        q = q0
        for _ in range(iterations):
            R, p = self.pose(q)
            q = q + checked_solve(self.jacobian(q), ca.vertcat(p_d - p, orientation_error(R_d, R)))
        return q

    # -- dynamics -----------------------------------------------------------------------
    def torques(self, q: ca.SX, qd: ca.SX, qdd: ca.SX) -> ca.SX:
        """Newton-Euler joint torques (with the chain's armature and friction)."""
        return self._torque(q, qd, qdd)

    def hand_dynamics(self, q: ca.SX, qd: ca.SX, u: ca.SX) -> ca.SX:
        """xdot = f(x, u) of eq 19 at the joint state (q, qd) that x stands for:
        (v, Phidot = M(Phi) Omega (eq 7), [vdot; Omegadot] = Jdot qd + J D^-1 (u - H - G))."""
        R, _ = self.pose(q)
        twist = self.jacobian(q) @ qd
        accel = self.bias(q, qd) + self.jacobian(q) @ self._accel(q, qd, u)
        return ca.vertcat(twist[:3], rpy_rates(rpy_of(R), twist[3:]), accel)

    def linearisation(self, q: ca.SX, qd: ca.SX, qdd: ca.SX) -> tuple[ca.SX, ca.SX]:
        """F = df/dx and L = df/du (eqs 24-28) at the nominal (q, qd) with u the Newton-Euler
        torque of the nominal acceleration qdd: linearisation_parts, and F's acceleration rows
        one by one (acceleration_row)."""
        parts = self.linearisation_parts(q, qd, qdd)
        return parts.F, parts.L

    def linearisation_parts(self, q: ca.SX, qd: ca.SX, qdd: ca.SX) -> Linearisation:
        """What F and L are made of, by AD (Linearisation).

        f depends on u through qdd = D^-1 (u - H - G) (eq 15); rather than differentiate that
        solve, the derivatives of qdd come from Newton-Euler's: dqdd/dz = -D^-1 dtau/dz at
        the nominal, dqdd/du = D^-1 (D is M). The rows of p and Phi are functions of x itself
        (pdot = v, Phidot = E^-1(Phi) Omega), so their structural zeros stay zeros; for the
        acceleration rows x = x(q, qd) is a local change of coordinates wherever J is
        invertible, so df/dx = df/dz (dx/dz)^-1, z = (q, qd); dx/dz is block lower
        triangular, [T J, 0; W, J] with T = blockdiag(I, E^-1) (eq 7) and W = d(J qd)/dq, so
        (dx/dz)^-1 = [J^-1 T^-1, 0; -J^-1 W J^-1 T^-1, J^-1]: one 6 x 6 solve."""
        zq, zqd, zqdd = ca.SX.sym("zq", N), ca.SX.sym("zqd", N), ca.SX.sym("zqdd", N)
        R, _ = self.pose(zq)
        J = self.jacobian(zq)
        twist = J @ zqd
        rpy = rpy_of(R)
        z = ca.vertcat(zq, zqd)
        accel = self.bias(zq, zqd) + J @ zqdd  # [vdot; Omegadot] at qdd (eq 10)
        # the rows of (p, Phi) are functions of x alone: pdot = v, Phidot = E^-1(Phi) Omega
        phi, omega = ca.SX.sym("phi", 3), ca.SX.sym("omega", 3)
        rates = rpy_rates(phi, omega)
        angular = ca.Function("angular", [phi, omega], [ca.jacobian(rates, phi), ca.jacobian(rates, omega)])
        parts = ca.Function(
            "parts",
            [zq, zqd, zqdd],
            [
                ca.jacobian(accel, z),
                J,
                self._torque_derivatives(zq, zqd, zqdd),
                ca.jacobian(twist, zq),
                self._mass(zq),
                rpy_rate_map(rpy),
                rpy,
                twist[3:],
            ],
        )
        dadz, J, dtaudz, W, M, E, rpy, omega_n = parts(q, qd, qdd)
        D, Einv = angular(rpy, omega_n)
        top = ca.blockcat([[ca.SX(3, 6), ca.SX.eye(3), ca.SX(3, 3)], [ca.SX(3, 3), D, ca.SX(3, 3), Einv]])
        J_Minv = cholesky_solve_matrix(M, J.T).T  # J D^-1 (M symmetric)
        return Linearisation(top, dadz, J_Minv, dtaudz, W, ca.solve(J, ca.SX.eye(N)), E)


@dataclasses.dataclass(frozen=True)
class Linearisation:
    """F and L's parts at the nominal: F's rows of (p, Phi) ``top`` (6 x 12), the derivatives
    of the hand acceleration at the nominal qdd and of the Newton-Euler torques with respect to
    z = (q, qd) (``dadz``, ``dtaudz``, 6 x 12), J D^-1 (``J_Minv``, L's acceleration rows),
    W = d(J qd)/dq, J^-1 (``Jinv``) and the Euler-rate map E (eq 7)."""

    top: ca.SX
    dadz: ca.SX
    J_Minv: ca.SX
    dtaudz: ca.SX
    W: ca.SX
    Jinv: ca.SX
    E: ca.SX

    @property
    def F(self) -> ca.SX:
        """df/dx: ``top`` over the acceleration rows, each by acceleration_row."""
        rows = [
            acceleration_row(self.dadz[i, :], self.J_Minv[i, :], self.dtaudz, self.W, self.Jinv, self.E)
            for i in range(N)
        ]
        return ca.vertcat(self.top, *rows)

    @property
    def L(self) -> ca.SX:
        """df/du: zero over J D^-1."""
        return ca.vertcat(ca.SX(6, N), self.J_Minv)


def acceleration_row(dadz: ca.SX, J_Minv: ca.SX, dtaudz: ca.SX, W: ca.SX, Jinv: ca.SX, E: ca.SX) -> ca.SX:
    """Row i of F's acceleration rows (1 x 12) from row i of dadz and of J D^-1: the row of
    df/dz = da/dz - (J D^-1) dtau/dz, then times (dx/dz)^-1 (linearisation_parts):
    [(df/dq - right W) J^-1 T^-1, right] with right = df/dqd J^-1."""
    dfdz = dadz - J_Minv @ dtaudz
    right = dfdz[:, N:] @ Jinv
    left = (dfdz[:, :N] - right @ W) @ Jinv @ ca.diagcat(ca.SX.eye(3), E)
    return ca.horzcat(left, right)


HAND_POSE, HAND_DISTANCE = "hand_pose", "hand_distance"


def hand_kernels(hand: Hand) -> list[Kernel]:
    """hand_pose(q): the 4x4 pose of the frame the laws control (tip times tool), what a desired
    path starts from; hand_distance(q, pose_d): how far pose_d is from it, the distance between
    the origins [m] and the angle of the rotation between them [rad]."""
    q, pose_d = ca.SX.sym("q", N), ca.SX.sym("pose_d", 16)
    R, p = hand.pose(q)
    R_d, p_d = pose_rows(pose_d)
    pose = ca.vertcat(ca.horzcat(R, p), ca.SX(ca.DM([[0, 0, 0, 1]])))
    return [
        make_kernel(
            HAND_POSE,
            "The hand frame the law controls (the chain's tip frame times the law's tool) in "
            "the base frame, 4x4: a desired path starts here.",
            [("q", q)],
            [("pose", pose, (4, 4))],
        ),
        make_kernel(
            HAND_DISTANCE,
            "How far the desired hand pose (4x4, base frame) is from the hand: the "
            "distance between their origins [m] and the angle of the rotation between them [rad].",
            [("q", q), ("pose_d", pose_d, (4, 4))],
            [("distance", ca.vertcat(ca.norm_2(p_d - p), rotation_angle(R_d, R)), (2, 1))],
            guarded=True,
        ),
    ]


def start_check() -> StartCheck:
    """The first step after a reset refuses a pose_d more than START_DISTANCE or START_ANGLE
    from the hand (docs/python-api.md, "Controller classes")."""
    return StartCheck(
        HAND_DISTANCE,
        (START_DISTANCE, START_ANGLE),
        ("m", "rad"),
        "start the desired path at hand_pose(q), where the hand is, and move it from there",
    )


def discretise(F: ca.SX, L: ca.SX, T: float, terms: int = 4) -> tuple[ca.SX, ca.SX]:
    """A = exp(F T) and B = int_0^T exp(F s) ds L (eqs 29-32, F and L held over the period),
    by their series to ``terms`` terms (F T is small at servo rates)."""
    n = F.shape[0]
    A, S, term = ca.SX.eye(n), ca.SX.eye(n) * T, ca.SX.eye(n)
    for k in range(1, terms):
        term = term @ F * (T / k)
        A = A + term
        S = S + term * (T / (k + 1))
    return A, S @ L
