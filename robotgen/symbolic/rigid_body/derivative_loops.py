"""The derivative recursion of rnea_derivatives on a serial chain, as schedule loops
(robotgen.symbolic.schedule): the prologue holds the kinematics (each joint's axis S and its
body's inertia about the base origin, where sin/cos and the robot's constants are); every
per-joint step is one loop body, and the n^2 joint-pair terms are three loops.

Forward dynamics derivatives run the recursion twice over, as the articulated form would:
a velocity pass at qdd = 0 gives the bias forces and the composite inertias, hence
M_ij = S_i . Ic_j S_j (i <= j) and h_i = S_i . F_i; one factorisation gives
qdd = M^-1 (tau - h - tau_friction); an acceleration pass adds I_k (a_k - a_k|qdd=0) to the
body forces; then the pair terms of d tau/dq, dqd at that qdd, and d qdd/dz = -M^-1 d tau/dz
column by column. Joint-local records while composites are summed from the tip:
f (6), inertia (m, h, Ibar: 13), T (9), p (3)."""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.symbolic.kernel import row_major
from robotgen.symbolic.rigid_body.cholesky import (
    cholesky_factor,
    schedule_inverse_product,
    solve_coefficients,
    solve_with_coefficients,
)
from robotgen.symbolic.rigid_body.friction import friction_torque
from robotgen.symbolic.rigid_body.inertia import OriginInertia
from robotgen.symbolic.rigid_body.rnea_derivatives import (
    ancestor_term,
    base_acceleration,
    body_terms,
    forward_step,
    joint_outputs,
    kinematics_stage,
    subtree_term,
)
from robotgen.symbolic.rigid_body.spatial import motion_cross6
from robotgen.symbolic.schedule import (
    ABOVE,
    BELOW,
    DESCENDING,
    LOCAL,
    ONCE,
    RANGE,
    ScheduleBuilder,
    Slice,
    block,
    body,
    symbols,
)

INERTIA = OriginInertia.SIZE
inertia_of = OriginInertia.of_vector
F, I, T, P, RECORD = 0, 6, 19, 28, 31  # offsets in a joint's record (f, inertia, T, p), and its width


class _Chain:
    """The local arrays shared by both schedules and the slice helpers. REC holds n + 1
    records, the last zero (the tip's child)."""

    def __init__(
        self, b: ScheduleBuilder, tree: KinematicTree, kinematics: tuple[list[ca.SX], list[OriginInertia]], qd: ca.SX
    ):
        self.b, self.n = b, tree.n_joints
        n = self.n
        self.S, self.BODY = kinematics_stage(b, *kinematics)  # BODY: each body's own inertia
        self.REC = b.local(size=RECORD * (n + 1))
        b.prologue(Slice(LOCAL, self.REC, RECORD * n), ca.SX.zeros(RECORD, 1))
        self.V = b.local(size=6 * (n + 1))  # v of joint i at 6 (i + 1); the base's at 0
        self.A = b.local(size=6 * (n + 1))
        b.prologue(Slice(LOCAL, self.V), ca.SX.zeros(6, 1))
        b.prologue(Slice(LOCAL, self.A), base_acceleration(tree))
        self.QD = b.local(qd)
        self.FR = b.local(ca.densify(ca.diag(ca.jacobian(friction_torque(tree, qd), qd))))
        self.SDOT, self.ALPHA, self.U, self.W, self.GAMMA, self.LAM = (
            b.local(size=width * n) for width in (6, 6, 6, 3, 6, 6)
        )

    at = staticmethod(block)

    def rec(self, offset: int) -> Slice:
        return self.at(self.REC, RECORD, offset=offset)

    def composite_terms(self, V: int, A: int) -> None:
        """Each record: f, I, T, p of the body (from its inertia and the v, a in V, A, written
        at 6 (i + 1)) plus its child's record, from the tip: the subtree sums in one pass."""
        inertia, child, (v, a) = ca.SX.sym("I", INERTIA), ca.SX.sym("child", RECORD), symbols("v a")
        f, T_, p = body_terms(inertia_of(inertia), v, a)
        own = ca.vertcat(f, inertia, ca.vec(T_), p)
        self.b.loop(
            body("composite_terms", [inertia, v, a, child], [own + child]),
            DESCENDING,
            self.n,
            [self.at(self.BODY, INERTIA), self.at(V, 6, offset=6), self.at(A, 6, offset=6), self.rec(RECORD)],
            [self.rec(0)],
        )

    def pairs(
        self, dq: tuple[str, int] | None, dqd: tuple[str, int] | None, row_stride: int = 0, second_offset: int = 0
    ) -> None:
        """The pair terms into row-major n x n arrays: diagonal (with friction), below (i in
        the subtree of j), above (i an ancestor of j); rows ``row_stride`` apart (default n), the
        d tau/dqd array from element ``second_offset``. Either array may be None (not written
        by these loops: the d tau/dqd terms do not depend on qdd, so forward dynamics makes them
        while its factorisation is under way)."""
        n, at = self.n, self.at
        r = row_stride or n
        u, alpha, sdot, s, gamma, lam = symbols("u alpha sdot s gamma lam")
        w, fr = ca.SX.sym("w", 3), ca.SX.sym("fr")
        term_q, term_qd = subtree_term(u, w, alpha, sdot, s)
        anc_q, anc_qd = ancestor_term(s, gamma, lam)
        keep = [k for k, target in enumerate((dq, dqd)) if target is not None]

        def targets(i_stride: int, j_stride: int) -> list[Slice]:
            return [
                Slice(*target, offset, i_stride=i_stride, j_stride=j_stride)
                for target, offset in ((dq, 0), (dqd, second_offset))
                if target is not None
            ]

        def loop(name: str, inputs: list[ca.SX], terms: tuple, space: str, reads: list[Slice], i: int, j: int):
            used = [x for x in inputs if any(ca.depends_on(terms[k], x) for k in keep)]
            self.b.loop(
                body(name, used, [terms[k] for k in keep]),
                space,
                n,
                [read for x, read in zip(inputs, reads) if any(x is y for y in used)],
                targets(i, j),
            )

        loop(
            "diagonal_term",
            [u, w, alpha, sdot, s, fr],
            (term_q, term_qd + fr),
            RANGE,
            [at(self.U, 6), at(self.W, 3), at(self.ALPHA, 6), at(self.SDOT, 6), at(self.S, 6), at(self.FR, 1)],
            r + 1,
            0,
        )
        loop(
            "subtree_term",
            [u, w, alpha, sdot, s],
            (term_q, term_qd),
            BELOW,
            [at(self.U, 6), at(self.W, 3), at(self.ALPHA, 6, "j"), at(self.SDOT, 6, "j"), at(self.S, 6, "j")],
            r,
            1,
        )
        loop(
            "ancestor_term",
            [s, gamma, lam],
            (anc_q, anc_qd),
            ABOVE,
            [at(self.S, 6), at(self.GAMMA, 6, "j"), at(self.LAM, 6, "j")],
            r,
            1,
        )


def schedule_rnea_derivatives(
    b: ScheduleBuilder,
    tree: KinematicTree,
    kinematics: tuple,
    qd: ca.SX,
    qdd: ca.SX,
    dq: tuple[str, int],
    dqd: tuple[str, int],
) -> None:
    """d tau/dq and d tau/dqd at ``qdd`` into the row-major n x n arrays ``dq``, ``dqd``
    ((kind, index) of a schedule array); ``kinematics``: the tree's axes_and_inertias."""
    c = _Chain(b, tree, kinematics, qd)
    n, at = c.n, c.at
    QDD = b.local(qdd)
    v_p, a_p, s, sdot, alpha, f = symbols("v_p a_p s sdot alpha f")
    qd_i, qdd_i = ca.SX.sym("qd"), ca.SX.sym("qdd")
    b.loop(
        body("forward_pass", [v_p, a_p, s, qd_i, qdd_i], list(forward_step(v_p, a_p, s, qd_i, qdd_i))),
        RANGE,
        n,
        [at(c.V, 6), at(c.A, 6), at(c.S, 6), at(c.QD, 1), at(QDD, 1)],
        [at(c.V, 6, offset=6), at(c.A, 6, offset=6), at(c.SDOT, 6), at(c.ALPHA, 6)],
    )
    c.composite_terms(c.V, c.A)
    inertia, T_, p = ca.SX.sym("I", INERTIA), ca.SX.sym("T", 9), ca.SX.sym("p", 3)
    outputs = joint_outputs(inertia_of(inertia), ca.reshape(T_, 3, 3), p, s, sdot, f, alpha)
    b.loop(
        body("joint_outputs", [f, inertia, T_, p, s, sdot, alpha], list(outputs)),
        RANGE,
        n,
        [c.rec(F), c.rec(I), c.rec(T), c.rec(P), at(c.S, 6), at(c.SDOT, 6), at(c.ALPHA, 6)],
        [at(c.U, 6), at(c.W, 3), at(c.GAMMA, 6), at(c.LAM, 6)],
    )
    c.pairs(dq, dqd)


def schedule_forward_dynamics_derivatives(
    b: ScheduleBuilder,
    tree: KinematicTree,
    kinematics: tuple,
    qd: ca.SX,
    tau: ca.SX,
    targets: tuple[tuple[str, int], ...],
) -> int:
    """d qdd/dq, d qdd/dqd and M^-1 at qdd = FD(q, qd, tau) into the three row-major n x n
    ``targets`` ((kind, index) of schedule arrays); returns the local holding qdd. M^-1 is
    straight-line code in the factorisation's block."""
    c = _Chain(b, tree, kinematics, qd)
    n, at = c.n, c.at
    C = b.local(size=6 * (n + 1))  # the accelerations at qdd = 0
    b.prologue(Slice(LOCAL, C), base_acceleration(tree))
    RHS = b.local(tau - friction_torque(tree, qd))
    M, H, QDD, DF = (b.local(size=size) for size in (n * n, n, n, 6 * n))
    DFC = b.local(size=6 * (n + 1))  # subtree sums of DF, the last zero
    b.prologue(Slice(LOCAL, DFC, 6 * n), ca.SX.zeros(6, 1))
    COEFFICIENTS = b.local(size=2 * n * n + n)
    ROWS = b.local(size=2 * n * n)  # row i: d tau_i/dq, d tau_i/dqd

    v_p, c_p, a_p, s, sdot, alpha, f, df, df_child, u, c_i = symbols("v_p c_p a_p s sdot alpha f df df_child u c")
    qd_i, qdd_i = ca.SX.sym("qd"), ca.SX.sym("qdd")
    v, a_zero, sdot_out, _ = forward_step(v_p, c_p, s, qd_i, ca.SX(0))
    b.loop(
        body("velocity_pass", [v_p, c_p, s, qd_i], [v, a_zero, sdot_out]),
        RANGE,
        n,
        [at(c.V, 6), at(C, 6), at(c.S, 6), at(c.QD, 1)],
        [at(c.V, 6, offset=6), at(C, 6, offset=6), at(c.SDOT, 6)],
    )
    c.composite_terms(c.V, C)
    # u_i = Ic_i S_i; M_ij = S_i . u_j for i <= j (both triangles); h_i = S_i . F_i at qdd = 0
    inertia = ca.SX.sym("I", INERTIA)
    u_out = inertia_of(inertia).apply6(s)
    b.loop(
        body("joint_mass", [inertia, s, f], [u_out, ca.dot(s, u_out), ca.dot(s, f)]),
        RANGE,
        n,
        [c.rec(I), at(c.S, 6), c.rec(F)],
        [at(c.U, 6), Slice(LOCAL, M, i_stride=n + 1), at(H, 1)],
    )
    b.loop(
        body("mass_term", [s, u], [ca.dot(s, u)] * 2),
        ABOVE,
        n,
        [at(c.S, 6), at(c.U, 6, "j")],
        [Slice(LOCAL, M, i_stride=n, j_stride=1), Slice(LOCAL, M, i_stride=1, j_stride=n)],
    )
    m, h, rhs, coefficients = (
        ca.SX.sym(name, size) for name, size in (("M", n * n), ("h", n), ("rhs", n), ("coefficients", 2 * n * n + n))
    )
    armature = ca.diag(ca.vertcat(*(joint.armature for joint in tree.joints)))
    b.loop(
        body("factor", [m], [solve_coefficients(cholesky_factor(ca.reshape(m, n, n).T + armature))]),
        ONCE,
        1,
        [Slice(LOCAL, M)],
        [Slice(LOCAL, COEFFICIENTS)],
    )
    # while the factorisation's chain of divisions runs: the terms that do not depend on qdd
    # (w, lam and the d tau/dqd pairs)
    inertia, T_, p = ca.SX.sym("I", INERTIA), ca.SX.sym("T", 9), ca.SX.sym("p", 3)
    _, w, _, lam = joint_outputs(inertia_of(inertia), ca.reshape(T_, 3, 3), p, s, sdot, f, alpha)
    b.loop(
        body("velocity_outputs", [inertia, T_, p, s, sdot], [w, lam]),
        RANGE,
        n,
        [c.rec(I), c.rec(T), c.rec(P), at(c.S, 6), at(c.SDOT, 6)],
        [at(c.W, 3), at(c.LAM, 6)],
    )
    c.pairs(None, (LOCAL, ROWS), row_stride=2 * n, second_offset=n)
    b.loop(
        body("solve", [coefficients, h, rhs], [solve_with_coefficients(coefficients, rhs - h)]),
        ONCE,
        1,
        [Slice(LOCAL, COEFFICIENTS), Slice(LOCAL, H), Slice(LOCAL, RHS)],
        [Slice(LOCAL, QDD)],
    )
    # M^-1 = M^-1 I, the zeros of I dropping out of the straight-line code
    minv = ca.horzcat(*(solve_with_coefficients(coefficients, ca.SX.eye(n)[:, k]) for k in range(n)))
    # the last loop reads M^-1 from a local: the target's, or a copy of an output's
    copies = [] if targets[2][0] == LOCAL else [Slice(LOCAL, b.local(size=n * n))]
    MINV = (copies[0] if copies else Slice(*targets[2])).index
    b.loop(
        body("mass_inverse", [coefficients], [row_major(minv)] * (1 + len(copies))),
        ONCE,
        1,
        [Slice(LOCAL, COEFFICIENTS)],
        [Slice(*targets[2]), *copies],
    )
    a_full = a_p + s * qdd_i + sdot * qd_i  # as forward_step, with Sdot from the velocity pass
    alpha_out = -motion_cross6(s, a_p) - motion_cross6(sdot, v_p)
    b.loop(
        body(
            "acceleration_pass",
            [v_p, a_p, s, sdot, qd_i, qdd_i, c_i, inertia],
            [a_full, alpha_out, inertia_of(inertia).apply6(a_full - c_i)],
        ),
        RANGE,
        n,
        [
            at(c.V, 6),
            at(c.A, 6),
            at(c.S, 6),
            at(c.SDOT, 6),
            at(c.QD, 1),
            at(QDD, 1),
            at(C, 6, offset=6),
            at(c.BODY, INERTIA),
        ],
        [at(c.A, 6, offset=6), at(c.ALPHA, 6), at(DF, 6)],
    )
    # from the tip: the subtree sum of I_k (a_k - a_k|qdd=0), added to F, then gamma
    gamma = joint_outputs(inertia_of(inertia), ca.reshape(T_, 3, 3), p, s, sdot, f + df + df_child, alpha)[2]
    b.loop(
        body("joint_outputs", [f, df, df_child, inertia, T_, p, s, sdot, alpha], [df + df_child, gamma]),
        DESCENDING,
        n,
        [
            c.rec(F),
            at(DF, 6),
            at(DFC, 6, offset=6),
            c.rec(I),
            c.rec(T),
            c.rec(P),
            at(c.S, 6),
            at(c.SDOT, 6),
            at(c.ALPHA, 6),
        ],
        [at(DFC, 6), at(c.GAMMA, 6)],
    )
    c.pairs((LOCAL, ROWS), None, row_stride=2 * n)
    schedule_inverse_product(b, n, MINV, ROWS, 2 * n, [(targets[0], 0, -1.0), (targets[1], n, -1.0)])
    return QDD
