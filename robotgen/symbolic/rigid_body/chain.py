"""Every dynamic and kinematic quantity of a KinematicTree as CasADi SX expressions of
shared symbols q, qd, qdd, tau: the tree's coordinates. The algorithms work in its joints;
a tree with mimic joints maps its coordinates into them and their results back
(rigid_body/coupled.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.model.regrouping import regrouped_inertias
from robotgen.model.snap import snap_tree
from robotgen.symbolic.differentiation import reverse_jacobian
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.base_turn import base_axis, turned
from robotgen.symbolic.rigid_body.chain_loops import LOOPS_ABOVE_DOF
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rigid_body.christoffel import coriolis_from_forces, coriolis_matrix
from robotgen.symbolic.rigid_body.coriolis import coriolis_spatial
from robotgen.symbolic.rigid_body.coupled import CoupledCoordinates
from robotgen.symbolic.rigid_body.crba import crba
from robotgen.symbolic.rigid_body.friction import friction_torque
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.jacobian import geometric_jacobian, hand_jacobian, tip_bias_acceleration
from robotgen.symbolic.rigid_body.kinematics import forward_kinematics, joint_motions, joint_poses
from robotgen.symbolic.rigid_body.rnea import forward_pass, rnea
from robotgen.symbolic.rigid_body.rnea_derivatives import axes_and_inertias, rnea_derivatives


@dataclass(frozen=True, eq=False)
class Symbols:
    """The shared symbols of a leaf: q, qd, qdd, tau, each (n,)."""

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    tau: ca.SX

    @staticmethod
    def make(n: int) -> Symbols:
        """Fresh symbols q, qd, qdd, tau of size n."""
        return Symbols(ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("qdd", n), ca.SX.sym("tau", n))


# Above this many joints the AD Christoffel form (O(n^3) terms) is not even tried: at 12 it
# is already twice the spatial algorithm's size, at 30 seven times.
AD_CORIOLIS_MAX_DOF = 12


class ChainGraphs:
    """Lazily built expressions; each is built once and shared by the kernels using it."""

    def __init__(self, tree: KinematicTree, sym: Symbols, snap: bool = True):
        self.tree = tree = snap_tree(tree) if snap else tree
        self.sym = sym
        # the joints' q, qd, qdd (sym's own without a coupling); results go back through it
        self.coordinates = c = CoupledCoordinates(tree)
        self.q_joints, self.qd_joints, self.qdd_joints = c.positions(sym.q), c.rates(sym.qd), c.rates(sym.qdd)
        self.motions = joint_motions(tree, self.q_joints)
        # every algorithm below reads the bodies through these (the same torques, fewer terms)
        self.inertias = [OriginInertia.constant(p) for p in regrouped_inertias(tree)]
        self._cache: dict[str, Any] = {}  # built graphs, counts and choices by name

    def _get(self, key: str, build: Callable[[], Any]) -> Any:
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]

    def _fewest(self, inputs: list[ca.SX], candidates: list[ca.SX | None]) -> ca.SX:
        """The candidate CasADi's CSE leaves with fewest operations (the first on a tie)."""
        return min((c for c in candidates if c is not None), key=lambda e: count_operations(inputs, [e])["total"])

    def fk(self) -> ca.SX:
        """The tip pose directly or with the first joint's turn factored out (base_turn)."""

        def build():
            direct = forward_kinematics(self.tree, self.q_joints)
            return self._fewest([self.sym.q], [direct, self._turn(direct, 0)])

        return self._get("fk", build)

    def jacobian(self) -> ca.SX:
        """Directly or with the first joint's turn factored out, as tip_turned decides."""
        turned_form = self._turned("jacobian") if self.tip_turned() else None  # (not None when tip_turned)
        return turned_form if turned_form is not None else self._jacobian_direct()

    def _jacobian_direct(self) -> ca.SX:
        return self._get(
            "jacobian_direct", lambda: self.coordinates.columns(geometric_jacobian(self.tree, self.q_joints))
        )

    def _jacobian_dot_qd_direct(self) -> ca.SX:
        return self._get(
            "jdqd_direct",
            lambda: tip_bias_acceleration(self.tree, joint_poses(self.tree, self.motions), self.bias_pass()),
        )

    def _turned(self, name: str) -> ca.SX | None:
        """The Jacobian or Jdot qd at q_root = 0, turned by R(q_root); None if no such turn."""
        direct = self._jacobian_direct() if name == "jacobian" else self._jacobian_dot_qd_direct()
        return self._get(name + "_turned", lambda: self._turn(direct, 2))

    def _turn(self, expr: ca.SX, blocks: int) -> ca.SX | None:
        """base_turn's form of ``expr``; None also when the root joint's coordinate is not its
        own plain symbol or moves another joint (a mimic of it would turn with it)."""
        c = self.tree.coupling
        if c is not None:
            found = base_axis(self.tree)
            if found is None:
                return None
            root = found[0]
            if len(c.joints_of(c.coordinate[root])) > 1 or c.multiplier[root] != 1.0 or c.offset[root] != 0.0:
                return None
        return turned(self.tree, self.q_joints, expr, blocks)

    def tip_turned(self) -> bool:
        """Whether J and Jdot qd are built turned (base_turn), one choice for both, so that the
        fused servo terms compute the separate functions' bits: the form that leaves M, C qd + N,
        J and Jdot qd together with fewer operations (direct, Jdot qd shares nonlinear's forward
        pass; which form wins depends on the arm). Past LOOPS_ABOVE_DOF
        joints M and C qd + N are loops, not built straight-line to count, and J and Jdot qd are
        counted alone."""

        def build():
            s = self.sym
            if self._turned("jacobian") is None:
                return False
            shared = [self.mass(), self.nonlinear()] if self.tree.n_joints <= LOOPS_ABOVE_DOF else []
            direct = (self._jacobian_direct(), self._jacobian_dot_qd_direct())
            turned_forms = (self._turned("jacobian"), self._turned("jacobian_dot_qd"))
            if turned_forms[0] is None or turned_forms[1] is None:  # (_turn's condition is the tree's: both or neither)
                return False
            count = [
                count_operations([s.q, s.qd], [*shared, J, a])["total"]
                for J, a in (direct, (turned_forms[0], turned_forms[1]))
            ]
            return count[1] < count[0]

        return self._get("tip_turned", build)

    def jacobian_hand(self) -> ca.SX:
        """The tip Jacobian (6, n) in tip-frame coordinates (Whitney 1972, eq 7): blockdiag(R^T, R^T) J."""
        return self._get("jacobian_hand", lambda: self.coordinates.columns(hand_jacobian(self.tree, self.q_joints)))

    def jacobian_dot_qd(self) -> ca.SX:
        """From RNEA's forward pass at qdd = 0: directly (the pass nonlinear() uses too) or with
        the first joint's turn factored out, as tip_turned decides."""
        turned_form = self._turned("jacobian_dot_qd") if self.tip_turned() else None  # (not None when tip_turned)
        return turned_form if turned_form is not None else self._jacobian_dot_qd_direct()

    def bias_pass(self):
        """RNEA's forward pass at qdd = 0 with gravity, shared by nonlinear and Jdot qd."""
        return self._get("bias_pass", lambda: forward_pass(self.tree, self.motions, self.qd_joints, None))

    def mass(self) -> ca.SX:
        """M(q) (n, n) by the composite rigid-body algorithm, in the tree's coordinates."""
        return self._get(
            "mass", lambda: self.coordinates.matrix(crba(self.tree, self.motions, self.inertias), symmetric=True)
        )

    def axes_and_inertias(self):
        """Each joint's axis and each body's inertia in base coordinates: what every looped
        kernel (chain_loops, derivative_loops) starts from, as its kinematics stage."""
        return self._get("axes_and_inertias", lambda: axes_and_inertias(self.tree, self.motions, self.inertias))

    def coriolis(self) -> ca.SX:
        """Whichever of coriolis_candidates CasADi's CSE leaves with fewest operations."""
        return self._get(
            "coriolis", lambda: self._fewest([self.sym.q, self.sym.qd], list(self.coriolis_candidates().values()))
        )

    def coriolis_candidates(self) -> dict[str, ca.SX]:
        """The Christoffel-consistent C three ways: Christoffel symbols of M by AD (O(n^3)
        terms, compact for small arms), half the velocity Jacobian of the Coriolis forces,
        and the spatial O(n^2) algorithm (alone past AD_CORIOLIS_MAX_DOF joints). Which is
        smallest after CSE depends on the arm."""
        q, qd, c = self.sym.q, self.sym.qd, self.coordinates
        spatial = c.matrix(coriolis_spatial(self.tree, self.motions, self.inertias, self.qd_joints))
        if self.tree.n_joints > AD_CORIOLIS_MAX_DOF:
            return {"spatial": spatial}
        half = [inertia.scaled(0.5) for inertia in self.inertias]
        half_forces = c.forces(rnea(self.tree, self.motions, half, self.qd_joints, None, gravity=False))
        # C is Christoffel(M): where M reads no q_i (a base joint's, an axisymmetric last
        # body's), neither does C, and the forces' graph may take q_i = 0 (no sin/cos)
        unread = [i for i in range(self.tree.nq) if not ca.depends_on(self.mass(), q[i])]
        if unread:
            half_forces = ca.substitute(half_forces, q[unread], ca.SX.zeros(len(unread)))
        return {
            "christoffel": coriolis_matrix(self.mass(), q, qd),
            "forces": coriolis_from_forces(half_forces, qd),
            "spatial": spatial,
        }

    def friction(self) -> ca.SX:
        """Every joint's friction (the mimic joints' too) as coordinate forces."""
        return self._get("friction", lambda: self.coordinates.forces(friction_torque(self.tree, self.qd_joints)))

    def gravity(self) -> ca.SX:
        """Gravity torques N(q) (n,) by Newton-Euler at qd = qdd = 0."""
        return self._get(
            "gravity", lambda: self.coordinates.forces(rnea(self.tree, self.motions, self.inertias, None, None))
        )

    def nonlinear(self) -> ca.SX:
        """C(q, qd) qd + N(q, qd): Newton-Euler with qdd = 0, plus friction."""
        return self._get(
            "nonlinear",
            lambda: (
                self.coordinates.forces(
                    rnea(self.tree, self.motions, self.inertias, self.qd_joints, None, passes=self.bias_pass())
                )
                + self.friction()
            ),
        )

    def inverse_dynamics(self) -> ca.SX:
        """S^T tau(q_joints, S qd, S qdd) under a coupling."""

        def build():
            c, qdd = self.coordinates, self.qdd_joints
            armature = ca.vertcat(*[j.armature * qdd[i] for i, j in enumerate(self.tree.joints)])
            return (
                c.forces(rnea(self.tree, self.motions, self.inertias, self.qd_joints, qdd))
                + c.forces(armature)
                + self.friction()
            )

        return self._get("inverse_dynamics", build)

    def forward_dynamics(self) -> ca.SX:
        """qdd = M^-1 (tau - C qd - N) (n,), by L D L^T."""
        return self._get("forward_dynamics", lambda: cholesky_solve(self.mass(), self.sym.tau - self.nonlinear()))

    def inverse_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX]:
        """(d tau/dq, d tau/dqd): the recursion of rnea_derivatives or reverse sweeps of
        Newton-Euler (one per joint), whichever CasADi's CSE leaves with fewer operations
        (the sweeps on small arms, the recursion on longer ones)."""

        def build():
            s = self.sym
            recursion = self._rnea_derivatives()
            tau = self.inverse_dynamics()
            sweeps = (reverse_jacobian(tau, s.q), reverse_jacobian(tau, s.qd))
            count = tuple(count_operations([s.q, s.qd, s.qdd], list(d))["total"] for d in (recursion, sweeps))
            self._cache["id_derivatives_counts"] = count
            return recursion if count[0] <= count[1] else sweeps

        return self._get("id_derivatives", build)

    def _rnea_derivatives(self) -> tuple[ca.SX, ca.SX]:
        """rnea_derivatives' recursion; under a coupling in the joints' own symbols (it
        differentiates friction by them), then at q_joints = S q + c and taken back by the
        chain rule, d tau_r/dq = S^T (d tau/dq_joints) S and the same for qd."""
        s = self.sym
        if not self.coordinates.coupled:
            return rnea_derivatives(self.tree, self.motions, self.inertias, s.qd, s.qdd)
        joints = Symbols.make(self.tree.n_joints)
        dq, dqd = rnea_derivatives(self.tree, joint_motions(self.tree, joints.q), self.inertias, joints.qd, joints.qdd)
        dq, dqd = ca.substitute(
            [dq, dqd], [joints.q, joints.qd, joints.qdd], [self.q_joints, self.qd_joints, self.qdd_joints]
        )
        return self.coordinates.matrix(dq), self.coordinates.matrix(dqd)

    def id_derivatives_counts(self) -> tuple[int, int]:
        """Straight-line operations of the recursion and of the reverse sweeps; the fewer is
        inverse_dynamics_derivatives."""
        self.inverse_dynamics_derivatives()
        return self._cache["id_derivatives_counts"]

    def id_derivatives_ops(self) -> int:
        """Operations of inverse_dynamics_derivatives, straight-line."""
        return min(self.id_derivatives_counts())

    def jacobian_derivative(self) -> ca.SX:
        """dJ/dt = sum_k dJ/dq_k qd_k, by one forward sweep."""
        return self._get("jacobian_derivative", lambda: ca.jtimes(self.jacobian(), self.sym.q, self.sym.qd))
