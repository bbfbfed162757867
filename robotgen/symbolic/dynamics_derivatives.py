"""The derivatives of a leaf robot's dynamics M(q) qdd + C(q, qd) qd + N(q, qd) = tau, and a
discrete-time model with its Jacobians, as a trajectory optimiser or an MPC solver consumes
them.

Forward dynamics qdd = M^-1 (tau - C qd - N) is differentiated through inverse dynamics: at
qdd = FD(q, qd, tau), d qdd/dz = -M^-1 d tau/dz for z = q, qd (the implicit function
theorem), and d qdd/d tau = M^-1; one L D L^T factorisation of M serves every column.

Past DERIVATIVE_LOOPS_ABOVE_OPS the kernels of both are built as schedules (robotgen.symbolic.schedule):
on a serial chain the recursion's steps and joint pairs are loops (derivative_loops), and
M^-1 d tau/dz is a loop over the rows of M^-1, formed once (it is d qdd/d tau)."""

from __future__ import annotations

import casadi as ca

from robotgen.model.derivatives import RK4, SEMI_IMPLICIT_EULER
from robotgen.symbolic.differentiation import reverse_jacobian
from robotgen.symbolic.formulas import FormulaGraphs
from robotgen.symbolic.kernel import row_major
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.cholesky import (
    cholesky_factor,
    cholesky_inverse,
    cholesky_substitute_columns,
    schedule_inverse_product,
)
from robotgen.symbolic.rigid_body.derivative_loops import (
    schedule_forward_dynamics_derivatives,
    schedule_rnea_derivatives,
)
from robotgen.symbolic.rigid_body.rnea_derivatives import is_serial
from robotgen.symbolic.schedule import LOCAL, OUTPUT, RANGE, ScheduleBuilder, Slice, body

# Straight-line code grows with its operations: past this many operations of d tau/dq, dqd
# (forward dynamics' derivatives have more) the kernels are emitted with loops
# (robotgen.symbolic.schedule), so that they fit the instruction cache. Small arms, where CSE
# makes the derivatives small, stay straight-line.
DERIVATIVE_LOOPS_ABOVE_OPS = 3000
# Loops run an operation faster than straight-line code this long, so the recursion's loops
# are taken while they have at most 10% more operations than the straight-line sweeps. Past
# that the sweeps stay straight-line and forward dynamics' derivatives end in the loop over the
# rows of M^-1. (The figures behind both: docs/performance-log.md.)
RECURSION_LOOPS_WITHIN = 1.1


class DynamicsDerivatives:
    """Built on a leaf's graphs (ChainGraphs or FormulaGraphs) and their symbols."""

    def __init__(self, graphs: ChainGraphs | FormulaGraphs) -> None:
        self.graphs = graphs
        self.sym: Symbols = graphs.sym
        s = self.sym
        if isinstance(graphs, ChainGraphs):
            dq, dqd = graphs.inverse_dynamics_derivatives()
        else:
            tau = graphs.inverse_dynamics()
            dq, dqd = reverse_jacobian(tau, s.q), reverse_jacobian(tau, s.qd)
        self._id = ca.Function("id_derivatives", [s.q, s.qd, s.qdd], [dq, dqd])
        self._fd: ca.Function | None = None
        self._fd_derivatives: tuple[ca.SX, ca.SX, ca.SX, ca.SX] | None = None

    def inverse_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX]:
        """(d tau/dq, d tau/dqd), each (n, n), of inverse dynamics at (q, qd, qdd)."""
        s = self.sym
        dq, dqd = self._id(s.q, s.qd, s.qdd)
        return dq, dqd

    def inverse_dynamics_derivatives_schedule(self) -> ScheduleBuilder | None:
        """Outputs (d tau/dq, d tau/dqd), row-major, as loops; None: straight-line is better."""
        if not self._looped():
            return None
        s = self.sym
        n = s.q.shape[0]
        b = ScheduleBuilder([s.q, s.qd, s.qdd], [n * n, n * n])
        self._inverse_into(b, s.qdd, (OUTPUT, 0), (OUTPUT, 1))
        return b

    def forward_dynamics_derivatives_schedule(self) -> ScheduleBuilder | None:
        """Outputs (d qdd/dq, d qdd/dqd, M^-1), row-major, with loops; None: straight-line is
        better."""
        if not self._forward_large():
            return None
        s = self.sym
        n = s.q.shape[0]
        b = ScheduleBuilder([s.q, s.qd, s.tau], [n * n] * 3)
        if (chain := self._looped()) is not None:
            schedule_forward_dynamics_derivatives(
                b, chain.tree, chain.axes_and_inertias(), s.qd, s.tau, ((OUTPUT, 0), (OUTPUT, 1), (OUTPUT, 2))
            )
            return b
        factor = cholesky_factor(self.graphs.mass())  # forward_dynamics' own, after CSE
        inverse = row_major(cholesky_substitute_columns(factor, ca.SX.eye(n)))
        b.prologue(Slice(OUTPUT, 2), inverse)
        dq, dqd = self._id(s.q, s.qd, self.graphs.forward_dynamics())
        rows = b.local(row_major(ca.horzcat(dq, dqd)))
        schedule_inverse_product(b, n, b.local(inverse), rows, 2 * n, [((OUTPUT, 0), 0, -1.0), ((OUTPUT, 1), n, -1.0)])
        return b

    def discrete_dynamics_derivatives_schedule(self, integrator: str, dt: ca.SX) -> ScheduleBuilder | None:
        """Outputs (q+, qd+, A, B) of semi-implicit Euler as loops on a chain where forward
        dynamics' derivatives are (_looped); None otherwise (RK4 stays straight-line)."""
        chain = self._looped() if integrator == SEMI_IMPLICIT_EULER else None
        if chain is None:
            return None
        s = self.sym
        n = s.q.shape[0]
        b = ScheduleBuilder([s.q, s.qd, s.tau, dt], [n, n, 4 * n * n, 2 * n * n])
        Q, QD, DT, EYE = b.local(s.q), b.local(s.qd), b.local(dt), b.local(ca.SX.eye(n))
        FQ, FQD, MINV = (b.local(size=n * n) for _ in range(3))
        QDD = schedule_forward_dynamics_derivatives(
            b, chain.tree, chain.axes_and_inertias(), s.qd, s.tau, ((LOCAL, FQ), (LOCAL, FQD), (LOCAL, MINV))
        )
        # qd+ = qd + dt qdd, q+ = q + dt qd+; row i of A = [[I + dt^2 Fq, dt I + dt^2 Fqd], [dt Fq, I + dt Fqd]]
        # and of B = [dt^2 M^-1; dt M^-1]
        q, qd, qdd, h = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("qdd"), ca.SX.sym("dt")
        fq, fqd, minv, e = (ca.SX.sym(name, n) for name in ("fq", "fqd", "minv", "e"))
        qd_next = qd + h * qdd
        rows = [
            ca.vertcat(e + h * h * fq, h * e + h * h * fqd),
            ca.vertcat(h * fq, e + h * fqd),
            h * h * minv,
            h * minv,
        ]
        at = lambda array, width: Slice(LOCAL, array, i_stride=width)  # noqa: E731
        b.loop(
            body("step_rows", [q, qd, qdd, h, fq, fqd, minv, e], [q + h * qd_next, qd_next, *rows]),
            RANGE,
            n,
            [at(Q, 1), at(QD, 1), at(QDD, 1), Slice(LOCAL, DT), at(FQ, n), at(FQD, n), at(MINV, n), at(EYE, n)],
            [
                Slice(OUTPUT, 0, i_stride=1),
                Slice(OUTPUT, 1, i_stride=1),
                Slice(OUTPUT, 2, i_stride=2 * n),
                Slice(OUTPUT, 2, 2 * n * n, i_stride=2 * n),
                Slice(OUTPUT, 3, i_stride=n),
                Slice(OUTPUT, 3, n * n, i_stride=n),
            ],
        )
        return b

    def _inverse_into(self, b: ScheduleBuilder, qdd: ca.SX, dq: tuple[str, int], dqd: tuple[str, int]) -> None:
        """d tau/dq and d tau/dqd at ``qdd`` into two row-major arrays of ``b``: the recursion's
        pair loops on a serial chain, else straight-line in the prologue."""
        s = self.sym
        if (chain := self._looped()) is not None:
            schedule_rnea_derivatives(b, chain.tree, chain.axes_and_inertias(), s.qd, qdd, dq, dqd)
            return
        DQ, DQD = self._id(s.q, s.qd, qdd)
        b.prologue(Slice(*dq), row_major(DQ))
        b.prologue(Slice(*dqd), row_major(DQD))

    def _large(self) -> bool:
        """Whether the derivatives are too large for straight-line code (DERIVATIVE_LOOPS_ABOVE_OPS)."""
        g = self.graphs
        return isinstance(g, ChainGraphs) and g.id_derivatives_ops() > DERIVATIVE_LOOPS_ABOVE_OPS

    def _forward_large(self) -> bool:
        """Whether forward dynamics' derivatives (about twice the inverse's operations) are too
        large for straight-line code: past DERIVATIVE_LOOPS_ABOVE_OPS their solve runs faster as
        loops."""
        s = self.sym
        return self._large() or (
            isinstance(self.graphs, ChainGraphs)
            and count_operations([s.q, s.qd, s.tau], list(self.forward_dynamics_derivatives()[1:]))["total"]
            > DERIVATIVE_LOOPS_ABOVE_OPS
        )

    def _looped(self) -> ChainGraphs | None:
        """The chain's graphs if the recursion's loops are used (derivative_loops), else None:
        a large serial chain on which the recursion has at most RECURSION_LOOPS_WITHIN times the
        sweeps' operations, and no mimic joints (the recursion runs in the joints)."""
        g = self.graphs
        if not (self._large() and isinstance(g, ChainGraphs) and is_serial(g.tree) and g.tree.coupling is None):
            return None
        recursion, sweeps = g.id_derivatives_counts()
        return g if recursion <= RECURSION_LOOPS_WITHIN * sweeps else None

    def mass_inverse(self) -> ca.SX:
        """M^-1 (n, n) as L^-T D^-1 L^-1 (robotgen.symbolic.rigid_body.cholesky.cholesky_inverse)."""
        return cholesky_inverse(self.graphs.mass())

    def forward_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """(qdd, d qdd/dq, d qdd/dqd, d qdd/d tau = M^-1) at (q, qd, tau), built once."""
        if self._fd_derivatives is None:
            self._fd_derivatives = self._build_forward_dynamics_derivatives()
        return self._fd_derivatives

    def _build_forward_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        s = self.sym
        n = s.q.shape[0]
        qdd = self.graphs.forward_dynamics()  # its factorisation of M and this one are one after CSE
        dq, dqd = self._id(s.q, s.qd, qdd)
        solved = cholesky_substitute_columns(cholesky_factor(self.graphs.mass()), ca.horzcat(dq, dqd, ca.SX.eye(n)))
        return qdd, -solved[:, :n], -solved[:, n : 2 * n], solved[:, 2 * n :]

    def _forward(self) -> ca.Function:
        if self._fd is None:
            s = self.sym
            self._fd = ca.Function("fd_derivatives", [s.q, s.qd, s.tau], list(self.forward_dynamics_derivatives()))
        return self._fd

    def discrete_dynamics(self, integrator: str, dt: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(q+, qd+) after one step of length dt with tau held."""
        q_next, qd_next, _, _ = self._step(integrator, dt, with_jacobians=False)
        return q_next, qd_next

    def discrete_dynamics_derivatives(self, integrator: str, dt: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """(q+, qd+, A = d x+/d x, B = d x+/d tau), x = (q, qd)."""
        return self._step(integrator, dt, with_jacobians=True)

    def _step(self, integrator: str, dt: ca.SX, with_jacobians: bool):
        s = self.sym
        n = s.q.shape[0]
        I = ca.SX.eye(n)
        if integrator == SEMI_IMPLICIT_EULER:
            # qd+ = qd + dt qdd(q, qd, tau), q+ = q + dt qd+
            if not with_jacobians:
                qd_next = s.qd + dt * self.graphs.forward_dynamics()
                return s.q + dt * qd_next, qd_next, None, None
            qdd, Fq, Fqd, Minv = self._forward()(s.q, s.qd, s.tau)
            qd_next = s.qd + dt * qdd
            dqd = ca.horzcat(dt * Fq, I + dt * Fqd)
            dq = ca.horzcat(I, ca.SX(n, n)) + dt * dqd
            A = ca.vertcat(dq, dqd)
            B = ca.vertcat(dt * dt * Minv, dt * Minv)
            return s.q + dt * qd_next, qd_next, A, B
        if integrator != RK4:
            raise ValueError(f"unknown integrator {integrator!r}")
        # x+ = x + dt/6 (k1 + 2 k2 + 2 k3 + k4), k = (qd, qdd) at the four stages; with the
        # Jacobians, each stage's d k/d(x, tau) by the chain rule through the previous stage.
        fd = (
            self._forward()
            if with_jacobians
            else ca.Function("fd", [s.q, s.qd, s.tau], [self.graphs.forward_dynamics()])
        )
        weights, offsets = (1, 2, 2, 1), (0, 0.5, 0.5, 1)
        k_prev = None
        dk_prev = None
        sum_k = ca.SX.zeros(2 * n, 1)
        sum_dk = ca.SX.zeros(2 * n, 3 * n)
        eye_x = ca.horzcat(ca.SX.eye(2 * n), ca.SX(2 * n, n))  # d x/d(x, tau)
        for weight, offset in zip(weights, offsets):
            x = ca.vertcat(s.q, s.qd) if k_prev is None else ca.vertcat(s.q, s.qd) + offset * dt * k_prev
            q_k, qd_k = x[:n], x[n:]
            if with_jacobians:
                qdd, Fq, Fqd, Minv = fd(q_k, qd_k, s.tau)
                dx = eye_x if dk_prev is None else eye_x + offset * dt * dk_prev  # d x_stage/d(x, tau)
                # k = (qd_k, qdd(q_k, qd_k, tau)): d k = [d qd_k; Fq d q_k + Fqd d qd_k + M^-1 d tau]
                d_tau = ca.horzcat(ca.SX(n, 2 * n), ca.SX.eye(n))
                dk = ca.vertcat(dx[n:, :], Fq @ dx[:n, :] + Fqd @ dx[n:, :] + Minv @ d_tau)
                sum_dk = sum_dk + weight * dk
                dk_prev = dk
            else:
                qdd = fd(q_k, qd_k, s.tau)
            k = ca.vertcat(qd_k, qdd)
            sum_k = sum_k + weight * k
            k_prev = k
        x_next = ca.vertcat(s.q, s.qd) + dt / 6 * sum_k
        if not with_jacobians:
            return x_next[:n], x_next[n:], None, None
        J = eye_x + dt / 6 * sum_dk
        return x_next[:n], x_next[n:], J[:, : 2 * n], J[:, 2 * n :]
