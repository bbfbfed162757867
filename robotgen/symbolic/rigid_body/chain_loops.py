"""A long chain's or tree's dynamics as schedule loops (robotgen.symbolic.schedule), in base-frame
spatial vectors as in rnea_derivatives: the prologue holds the kinematics (each joint's axis
S_i and its body's inertia I_i about the base origin); loops make the velocity and
acceleration passes, the subtree composites from the tip, and the joint-pair terms.

    M_ij = S_i . Ic_j S_j (i <= j; Walker and Orin's composite rigid bodies), plus armature;
    tau_i = S_i . F_i, F_i the subtree sum of f_k = I_k a_k + v_k x* I_k v_k (Newton-Euler),
            plus armature qdd_i and friction;
    C_ij  = S_i . (Ic_m Sdot_j + Bc_m S_j), m = max(i, j), Sdot_j = v_j x S_j, Bc the subtree sum
            of B_k = 1/2 (v_k x* I_k - I_k v_k x + (I_k v_k) xbar), (f xbar) y = y x* f.

C is the Christoffel-consistent factorisation (Mdot - 2C skew: Idot - 2B = -(I v) xbar is
skew); B_k is half the B_k of rnea_derivatives, [[T_k / 2, 0], [-[p_k x], 0]]. With
u_i = Ic_i S_i, w_i = T_i^T S_i,ang + 2 p_i x S_i,lin and X_j = Ic_j Sdot_j + Bc_j S_j:
C_ij = u_i . Sdot_j + w_i . S_j,ang / 2 for i > j, S_i . X_j for i <= j.

Chains whose straight-line kernels pass the instruction cache (LOOPS_ABOVE_OPS) use these: the
code is O(n) in size, not O(n^2), and compiles in a fraction of the time.

A tree with mimic joints (rigid_body/coupled.py) runs the same loops in its joints, on
qd_joints = S qd and qdd_joints = S qdd, into local arrays; one block after them takes the
results to its coordinates, S^T M S, S^T tau, S^T C S. Its forward dynamics is no
articulated-body pass (the coupled joints are not a tree's): M and C qd + N so taken to the
coordinates, then an L D L^T solve in that block."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.symbolic.kernel import row_major
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rigid_body.coupled import CoupledCoordinates
from robotgen.symbolic.rigid_body.friction import friction_torque
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.rnea_derivatives import base_acceleration, body_terms, kinematics_stage
from robotgen.symbolic.rigid_body.spatial import force_cross6, motion_cross6
from robotgen.symbolic.schedule import (
    ABOVE,
    BELOW,
    DESCENDING,
    LOCAL,
    ONCE,
    OUTPUT,
    PAIRS,
    RANGE,
    ScheduleBuilder,
    Slice,
    block,
    body,
    symbols,
)

# Straight-line kernels past this many operations (~13 bytes each in x86-64 code) leave the
# instruction cache and take gcc superlinear time to compile: a serial chain's are loops then.
LOOPS_ABOVE_OPS = 5000
# The Coriolis matrix's loops cost few operations more than its straight-line form (O(n^2) terms
# against the Christoffel symbols' O(n^3)), so it turns to loops sooner, past 2500 operations.
# Which form runs faster depends on the core; the loops are taken for their code, several times
# smaller, where a microcontroller has a 4-16 kB instruction cache (docs/performance-log.md).
CORIOLIS_LOOPS_ABOVE_OPS = 2500
# Past this many joints every kernel built here is (Coriolis alone is ~36 n^2 operations).
LOOPS_ABOVE_DOF = 12


INERTIA = OriginInertia.SIZE
inertia_of = OriginInertia.of_vector


class ChainLoops:
    """Builds the schedules; each method fills a ScheduleBuilder whose inputs are the kernel's.

    A serial chain's joint i has parent i - 1: a parent's block is addressed by i and the
    subtree sums run "own plus the child's block". A branched tree (parents listed before their
    children) addresses parents through an index table, and a subtree sum adds each finished
    block into its parent's (the roots into a spare block n); its joint pairs are listed."""

    def __init__(self, tree: KinematicTree, kinematics: Callable[[], tuple[list[ca.SX], list[OriginInertia]]]):
        """``kinematics``: builds (or returns, once built) axes_and_inertias of ``tree``."""
        self.tree, self.kinematics, self.n = tree, kinematics, tree.n_joints
        self.coordinates = CoupledCoordinates(tree)
        self.parents = [joint.parent for joint in tree.joints]
        if any(p >= i for i, p in enumerate(self.parents)):
            raise ValueError("a tree's joints must come after their parents")
        self.serial = all(p == i - 1 for i, p in enumerate(self.parents))
        ancestors: list[list[int]] = []
        for p in self.parents:
            ancestors.append([] if p < 0 else ancestors[p] + [p])
        # (i, j) with i a strict ancestor of j, and with j a strict ancestor of i
        self.ancestor_pairs = [(i, j) for j in range(self.n) for i in ancestors[j]]
        self.descendant_pairs = [(i, j) for i in range(self.n) for j in ancestors[i]]

    def _parent_state(self, array: int, width: int) -> Slice:
        """The parent's block of a per-joint state stored at i + 1 (the base's at 0)."""
        if self.serial:
            return block(array, width)
        return Slice(LOCAL, array, 0, i_stride=width, i_table=tuple(p + 1 for p in self.parents))

    def _parent_block(self, array: int, width: int) -> Slice:
        """The parent's block of a per-joint array of n + 1 blocks (roots: block n)."""
        return Slice(LOCAL, array, 0, i_stride=width, i_table=tuple(p if p >= 0 else self.n for p in self.parents))

    def _subtree_sum(
        self, b: ScheduleBuilder, name: str, inputs: list[ca.SX], reads: list[Slice], own: ca.SX, array: int
    ) -> None:
        """Block i of ``array`` (n + 1 blocks of own's size, zero before) = own_i + its children's
        blocks, from the tip."""
        width, n = own.numel(), self.n
        if self.serial:
            child = ca.SX.sym("child", width)
            b.loop(
                body(name, [*inputs, child], [own + child]),
                DESCENDING,
                n,
                [*reads, block(array, width, offset=width)],
                [block(array, width)],
            )
            return
        children, parent = ca.SX.sym("children", width), ca.SX.sym("parent", width)
        b.loop(
            body(name, [*inputs, children, parent], [own + children, parent + own + children]),
            DESCENDING,
            n,
            [*reads, block(array, width), self._parent_block(array, width)],
            [block(array, width), self._parent_block(array, width)],
        )

    def _zeros(self, b: ScheduleBuilder, width: int) -> int:
        """A local of n + 1 blocks for a subtree sum: the spare block zero (every block for a tree)."""
        n = self.n
        array = b.local(size=width * (n + 1))
        if self.serial:
            b.prologue(Slice(LOCAL, array, width * n), ca.SX.zeros(width, 1))
        else:
            b.prologue(Slice(LOCAL, array), ca.SX.zeros(width * (n + 1), 1))
        return array

    def _pairs(
        self,
        b: ScheduleBuilder,
        name: str,
        inputs: list[ca.SX],
        outputs: list[ca.SX],
        reads: list[Slice],
        writes: list[Slice],
        ancestor: bool,
    ) -> None:
        """A loop over the joint pairs (i, j) with i a strict ancestor of j (``ancestor``) or j one
        of i: on a serial chain i < j (ABOVE) or i > j (BELOW)."""
        f = body(name, inputs, outputs)
        if self.serial:
            b.loop(f, ABOVE if ancestor else BELOW, self.n, reads, writes)
        else:
            b.loop(f, PAIRS, self.n, reads, writes, self.ancestor_pairs if ancestor else self.descendant_pairs)

    # -- pieces ---------------------------------------------------------------------------

    def _kinematics(self, b: ScheduleBuilder) -> tuple[int, int]:
        return kinematics_stage(b, *self.kinematics())

    def _composite_inertias(self, b: ScheduleBuilder, BODY: int) -> int:
        """Ic_i (13 per joint, n + 1 of them), summed from the tip."""
        IC = self._zeros(b, INERTIA)
        own = ca.SX.sym("I", INERTIA)
        self._subtree_sum(b, "composite_inertia", [own], [block(BODY, INERTIA)], own, IC)
        return IC

    def _velocities(self, b: ScheduleBuilder, S: int, qd: ca.SX) -> tuple[int, int, int]:
        """qd, v (at 6 (i + 1), the base's 0 at 0) and Sdot = v x S of each joint."""
        n = self.n
        QD, V, SDOT = b.local(qd), b.local(size=6 * (n + 1)), b.local(size=6 * n)
        b.prologue(Slice(LOCAL, V), ca.SX.zeros(6, 1))
        v_p, s = symbols("v_p s")
        qd_i = ca.SX.sym("qd")
        v = v_p + s * qd_i
        b.loop(
            body("velocity_pass", [v_p, s, qd_i], [v, motion_cross6(v, s)]),
            RANGE,
            n,
            [self._parent_state(V, 6), block(S, 6), block(QD, 1)],
            [block(V, 6, offset=6), block(SDOT, 6)],
        )
        return QD, V, SDOT

    def _torques(
        self,
        b: ScheduleBuilder,
        S: int,
        BODY: int,
        velocities: tuple[int, int, int],
        qdd: ca.SX | None,
        extra: ca.SX,
        target: Slice,
    ) -> None:
        """tau_i = S_i . F_i + extra_i into ``target`` (Newton-Euler): accelerations from the
        base's (-g), body forces, their subtree sums from the tip. ``velocities``: _velocities'
        arrays; ``qdd`` None: at qdd = 0 (C qd + N)."""
        n = self.n
        QD, V, SDOT = velocities
        A = b.local(size=6 * (n + 1))
        b.prologue(Slice(LOCAL, A), base_acceleration(self.tree))
        EXTRA = b.local(extra)
        F = self._zeros(b, 6)
        a_p, s, sdot, v, f = symbols("a_p s sdot v f")
        qd_i, qdd_i = ca.SX.sym("qd"), ca.SX.sym("qdd")
        inertia = ca.SX.sym("I", INERTIA)
        I = inertia_of(inertia)
        inputs, reads, a = (
            [a_p, s, sdot, qd_i],
            [self._parent_state(A, 6), block(S, 6), block(SDOT, 6), block(QD, 1)],
            a_p + sdot * qd_i,
        )
        if qdd is not None:
            QDD = b.local(qdd)
            inputs, reads, a = inputs + [qdd_i], reads + [block(QDD, 1)], a + s * qdd_i
        b.loop(body("acceleration_pass", inputs, [a]), RANGE, n, reads, [block(A, 6, offset=6)])
        force = I.apply6(a_p) + force_cross6(v, I.apply6(v))
        self._subtree_sum(
            b,
            "body_force",
            [inertia, a_p, v],
            [block(BODY, INERTIA), block(A, 6, offset=6), block(V, 6, offset=6)],
            force,
            F,
        )
        e = ca.SX.sym("e")
        b.loop(
            body("joint_torque", [s, f, e], [ca.dot(s, f) + e]),
            RANGE,
            n,
            [block(S, 6), block(F, 6), block(EXTRA, 1)],
            [target],
        )

    def _mass(self, b: ScheduleBuilder, S: int, IC: int, target: tuple[str, int]) -> None:
        """M (row-major n x n) into ``target``."""
        n = self.n
        s, u = symbols("s u")
        inertia, arm = ca.SX.sym("I", INERTIA), ca.SX.sym("armature")
        U = b.local(size=6 * n)
        ARM = b.local(ca.vertcat(*(joint.armature for joint in self.tree.joints)))
        u_out = inertia_of(inertia).apply6(s)
        b.loop(
            body("mass_diagonal", [inertia, s, arm], [u_out, ca.dot(s, u_out) + arm]),
            RANGE,
            n,
            [block(IC, INERTIA), block(S, 6), block(ARM, 1)],
            [block(U, 6), Slice(*target, i_stride=n + 1)],
        )
        self._pairs(
            b,
            "mass_term",
            [s, u],
            [ca.dot(s, u)] * 2,
            [block(S, 6), block(U, 6, "j")],
            [Slice(*target, i_stride=n, j_stride=1), Slice(*target, i_stride=1, j_stride=n)],
            ancestor=True,
        )

    def _extra(self, qd: ca.SX | None, qdd: ca.SX | None) -> ca.SX:
        """Armature qdd + friction(qd): what each joint adds to S . F."""
        extra = ca.SX.zeros(self.n, 1)
        if qdd is not None:
            extra += ca.vertcat(*(joint.armature * qdd[i] for i, joint in enumerate(self.tree.joints)))
        if qd is not None:
            extra += friction_torque(self.tree, qd)
        return extra

    # -- a coupled tree's joint results, taken to its coordinates --------------------------------

    def _joint_matrix(self, b: ScheduleBuilder) -> int:
        """A local for an n x n joint matrix (row-major), zero where the loops write nothing."""
        array = b.local(size=self.n * self.n)
        b.prologue(Slice(LOCAL, array), ca.SX.zeros(self.n * self.n, 1))
        return array

    def _to_coordinates(
        self,
        b: ScheduleBuilder,
        name: str,
        arrays: list[tuple[int, str]],
        result,
        target: Slice,
        tau: ca.SX | None = None,
    ) -> None:
        """One block reading the joint results ``arrays`` ((local, kind) each, taken to the
        coordinates: S^T M S for a "matrix" or "symmetric" one (row-major), S^T tau for a
        "vector") and the coordinate forces ``tau`` if given, writing ``result`` of them all (a
        column) into ``target``."""
        n, c = self.n, self.coordinates
        inputs, values, reads = [], [], [Slice(LOCAL, array) for array, _ in arrays]
        for _, kind in arrays:
            x = ca.SX.sym(kind, n if kind == "vector" else n * n)
            inputs.append(x)
            values.append(
                c.forces(x) if kind == "vector" else c.matrix(ca.reshape(x, n, n).T, symmetric=kind == "symmetric")
            )
        if tau is not None:
            inputs.append(ca.SX.sym("tau", tau.numel()))
            values.append(inputs[-1])
            reads.append(Slice(LOCAL, b.local(tau)))
        b.loop(body(name, inputs, [result(*values)]), ONCE, 1, reads, [target])

    # -- kernels ----------------------------------------------------------------------------

    def mass(self, b: ScheduleBuilder) -> None:
        """Schedule M (n, n) as loops: composite inertias from the tip, then each joint pair."""
        S, BODY = self._kinematics(b)
        if not self.coordinates.coupled:
            self._mass(b, S, self._composite_inertias(b, BODY), (OUTPUT, 0))
            return
        IC = self._composite_inertias(b, BODY)
        M = self._joint_matrix(b)
        self._mass(b, S, IC, (LOCAL, M))
        self._to_coordinates(b, "mass_coordinates", [(M, "symmetric")], row_major, Slice(OUTPUT, 0))

    def inverse_dynamics(self, b: ScheduleBuilder, qd: ca.SX, qdd: ca.SX | None) -> None:
        """Newton-Euler torques; qdd None: C qd + N (nonlinear)."""
        S, BODY = self._kinematics(b)
        c = self.coordinates
        qd, qdd = c.rates(qd), (None if qdd is None else c.rates(qdd))
        if not c.coupled:
            self._torques(
                b, S, BODY, self._velocities(b, S, qd), qdd, self._extra(qd, qdd), Slice(OUTPUT, 0, i_stride=1)
            )
            return
        TAU = b.local(size=self.n)
        self._torques(b, S, BODY, self._velocities(b, S, qd), qdd, self._extra(qd, qdd), Slice(LOCAL, TAU, i_stride=1))
        self._to_coordinates(b, "force_coordinates", [(TAU, "vector")], lambda tau: tau, Slice(OUTPUT, 0))

    def coriolis(self, b: ScheduleBuilder, qd: ca.SX) -> None:
        """Schedule C(q, qd) (n, n) as loops: the spatial algorithm's composites from the tip."""
        n = self.n
        S, BODY = self._kinematics(b)
        _, V, SDOT = self._velocities(b, S, self.coordinates.rates(qd))
        REC = self._zeros(b, 25)  # composites: inertia (13), T (9), p (3)
        inertia, (v, s, sdot, u, x) = ca.SX.sym("I", INERTIA), symbols("v s sdot u x")
        _, T_, p = body_terms(inertia_of(inertia), v, ca.SX.zeros(6, 1))
        self._subtree_sum(
            b,
            "composite_terms",
            [inertia, v],
            [block(BODY, INERTIA), block(V, 6, offset=6)],
            ca.vertcat(inertia, ca.vec(T_), p),
            REC,
        )
        record = ca.SX.sym("record", 25)
        Ic, T, pc = inertia_of(record[:INERTIA]), ca.reshape(record[INERTIA:22], 3, 3), record[22:25]
        B_S = ca.vertcat(T @ s[:3] / 2, -ca.cross(pc, s[:3]))
        U, W, X = b.local(size=6 * n), b.local(size=3 * n), b.local(size=6 * n)
        b.loop(
            body(
                "joint_terms",
                [record, s, sdot],
                [Ic.apply6(s), (T.T @ s[:3] + 2 * ca.cross(pc, s[3:])) / 2, Ic.apply6(sdot) + B_S],
            ),
            RANGE,
            n,
            [block(REC, 25), block(S, 6), block(SDOT, 6)],
            [block(U, 6), block(W, 3), block(X, 6)],
        )
        w = ca.SX.sym("w", 3)
        out = (LOCAL, self._joint_matrix(b)) if self.coordinates.coupled else (OUTPUT, 0)
        b.loop(
            body("diagonal_term", [s, x], [ca.dot(s, x)]),
            RANGE,
            n,
            [block(S, 6), block(X, 6)],
            [Slice(*out, i_stride=n + 1)],
        )
        self._pairs(
            b,
            "subtree_term",
            [u, w, sdot, s],
            [ca.dot(u, sdot) + ca.dot(w, s[:3])],
            [block(U, 6), block(W, 3), block(SDOT, 6, "j"), block(S, 6, "j")],
            [Slice(*out, i_stride=n, j_stride=1)],
            ancestor=False,
        )
        self._pairs(
            b,
            "ancestor_term",
            [s, x],
            [ca.dot(s, x)],
            [block(S, 6), block(X, 6, "j")],
            [Slice(*out, i_stride=n, j_stride=1)],
            ancestor=True,
        )
        if self.coordinates.coupled:
            self._to_coordinates(b, "coriolis_coordinates", [(out[1], "matrix")], row_major, Slice(OUTPUT, 0))

    def forward_dynamics(self, b: ScheduleBuilder, qd: ca.SX, tau: ca.SX) -> None:
        """qdd by the articulated-body algorithm (Featherstone 2008, Table 7.1) in base-frame
        vectors, O(n): from the tip, the articulated inertia and bias force of each subtree,
        I^A_i = I_i + sum of I^a over its children, p^A_i = v_i x* I_i v_i + sum of p^a, U = I^A S, D = S . U +
        armature, u = tau - friction - S . p^A, I^a = I^A - U U^T / D, p^a = p^A + I^a c + U u / D
        (c = Sdot qd); then from the base, a'_i = a_parent + c_i, qdd_i = (u_i - U_i . a'_i) / D_i
        and a_i = a'_i + S_i qdd_i, the base's a = -g. A coupled tree: _coupled_forward_dynamics."""
        if self.coordinates.coupled:
            self._coupled_forward_dynamics(b, qd, tau)
            return
        n = self.n
        S, BODY = self._kinematics(b)
        QD, V, SDOT = self._velocities(b, S, qd)
        RHS = b.local(tau - friction_torque(self.tree, qd))
        ARM = b.local(ca.vertcat(*(joint.armature for joint in self.tree.joints)))
        ART = self._zeros(b, 42)  # I^a (36, by columns) and p^a (6) added up per parent
        UD = b.local(size=8 * n)  # U (6), D, u of each joint
        A = b.local(size=6 * (n + 1))
        b.prologue(Slice(LOCAL, A), base_acceleration(self.tree))
        QDD = b.local(size=n)
        inertia, children, (v, s, sdot, a_p, U) = (
            ca.SX.sym("I", INERTIA),
            ca.SX.sym("children", 42),
            symbols("v s sdot a_p U"),
        )
        qd_i, rhs, arm, D, u = (ca.SX.sym(name) for name in ("qd", "rhs", "armature", "D", "u"))
        I = inertia_of(inertia)
        H = ca.skew(I.h)
        spatial = ca.vertcat(ca.horzcat(I.Ibar, H), ca.horzcat(H.T, I.m * ca.SX.eye(6)[3:, 3:]))
        IA = spatial + ca.reshape(children[:36], 6, 6)
        pA = force_cross6(v, I.apply6(v)) + children[36:]
        U_out = IA @ s
        D_out = ca.dot(s, U_out) + arm
        u_out = rhs - ca.dot(s, pA)
        Ia = IA - U_out @ U_out.T / D_out
        pa = pA + Ia @ (sdot * qd_i) + U_out * (u_out / D_out)
        articulated = ca.vertcat(ca.vec(Ia), pa)
        inputs = [inertia, v, s, sdot, qd_i, rhs, arm]
        reads = [
            block(BODY, INERTIA),
            block(V, 6, offset=6),
            block(S, 6),
            block(SDOT, 6),
            block(QD, 1),
            block(RHS, 1),
            block(ARM, 1),
        ]
        if self.serial:  # block i holds joint i's own I^a, p^a; its child's is block i + 1
            b.loop(
                body("articulated", [*inputs, children], [articulated, ca.vertcat(U_out, D_out, u_out)]),
                DESCENDING,
                n,
                [*reads, block(ART, 42, offset=42)],
                [block(ART, 42), block(UD, 8)],
            )
        else:  # block i holds the sum of its children's I^a, p^a; joint i adds its own into its parent's
            parent = ca.SX.sym("parent", 42)
            b.loop(
                body(
                    "articulated", [*inputs, children, parent], [parent + articulated, ca.vertcat(U_out, D_out, u_out)]
                ),
                DESCENDING,
                n,
                [*reads, block(ART, 42), self._parent_block(ART, 42)],
                [self._parent_block(ART, 42), block(UD, 8)],
            )
        a_prime = a_p + sdot * qd_i
        qdd = (u - ca.dot(U, a_prime)) / D
        b.loop(
            body("acceleration", [a_p, U, D, u, s, sdot, qd_i], [qdd, a_prime + s * qdd]),
            RANGE,
            n,
            [
                self._parent_state(A, 6),
                block(UD, 8),
                block(UD, 8, offset=6),
                block(UD, 8, offset=7),
                block(S, 6),
                block(SDOT, 6),
                block(QD, 1),
            ],
            [block(QDD, 1), block(A, 6, offset=6)],
        )
        x = ca.SX.sym("qdd", n)
        b.loop(body("copy", [x], [x]), ONCE, 1, [Slice(LOCAL, QDD)], [Slice(OUTPUT, 0)])

    def _coupled_forward_dynamics(self, b: ScheduleBuilder, qd: ca.SX, tau: ca.SX) -> None:
        """qdd = (S^T M S)^-1 (tau - S^T (C qd + N)) by L D L^T: M and the bias forces by the
        loops in the joints, the rest in one block."""
        M, H = self._joint_mass_and_bias(b, qd)
        self._to_coordinates(
            b,
            "coupled_forward_dynamics",
            [(M, "symmetric"), (H, "vector")],
            lambda m, h, t: cholesky_solve(m, t - h),
            Slice(OUTPUT, 0),
            tau,
        )

    def _joint_mass_and_bias(self, b: ScheduleBuilder, qd: ca.SX) -> tuple[int, int]:
        """Locals of a coupled tree's joint M and C qd + N (with friction) at qd_joints = S qd."""
        S, BODY = self._kinematics(b)
        qd = self.coordinates.rates(qd)
        H = b.local(size=self.n)
        self._torques(b, S, BODY, self._velocities(b, S, qd), None, self._extra(qd, None), Slice(LOCAL, H, i_stride=1))
        M = self._joint_matrix(b)
        self._mass(b, S, self._composite_inertias(b, BODY), (LOCAL, M))
        return M, H

    def servo_terms(self, b: ScheduleBuilder, qd: ca.SX, jacobian: ca.SX, jacobian_dot_qd: ca.SX) -> None:
        """M, C qd + N, and the tip's J and Jdot qd (straight-line, O(n)) in one call."""
        b.prologue(Slice(OUTPUT, 2), row_major(jacobian))
        b.prologue(Slice(OUTPUT, 3), jacobian_dot_qd)
        if self.coordinates.coupled:
            M, H = self._joint_mass_and_bias(b, qd)
            self._to_coordinates(b, "mass_coordinates", [(M, "symmetric")], row_major, Slice(OUTPUT, 0))
            self._to_coordinates(b, "force_coordinates", [(H, "vector")], lambda h: h, Slice(OUTPUT, 1))
            return
        S, BODY = self._kinematics(b)
        self._torques(b, S, BODY, self._velocities(b, S, qd), None, self._extra(qd, None), Slice(OUTPUT, 1, i_stride=1))
        self._mass(b, S, self._composite_inertias(b, BODY), (OUTPUT, 0))
