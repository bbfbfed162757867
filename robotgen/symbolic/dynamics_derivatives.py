"""The derivatives of a leaf robot's dynamics M(q) qdd + C(q, qd) qd + N(q, qd) = tau, and a
discrete-time model with its Jacobians, as a trajectory optimiser or an MPC solver consumes
them.

Forward dynamics qdd = M^-1 (tau - C qd - N) is differentiated through inverse dynamics: at
qdd = FD(q, qd, tau), d qdd/dz = -M^-1 d tau/dz for z = q, qd (the implicit function
theorem), and d qdd/d tau = M^-1; one Cholesky factorisation of M serves every column."""
from __future__ import annotations

import casadi as ca

from robotgen.model.derivatives import RK4, SEMI_IMPLICIT_EULER
from robotgen.symbolic.differentiation import reverse_jacobian
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.cholesky import cholesky_factor, cholesky_solve_matrix, cholesky_substitute_columns


class DynamicsDerivatives:
    """Built on a leaf's graphs (ChainGraphs or FormulaGraphs) and their symbols."""

    def __init__(self, graphs):
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

    def inverse_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX]:
        s = self.sym
        dq, dqd = self._id(s.q, s.qd, s.qdd)
        return dq, dqd

    def mass_inverse(self) -> ca.SX:
        n = self.sym.q.shape[0]
        return cholesky_solve_matrix(self.graphs.mass(), ca.SX.eye(n))

    def forward_dynamics_derivatives(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """(qdd, d qdd/dq, d qdd/dqd, d qdd/d tau = M^-1) at (q, qd, tau)."""
        s = self.sym
        n = s.q.shape[0]
        qdd = self.graphs.forward_dynamics()  # its factorisation of M and this one are one after CSE
        dq, dqd = self._id(s.q, s.qd, qdd)
        solved = cholesky_substitute_columns(cholesky_factor(self.graphs.mass()), ca.horzcat(dq, dqd, ca.SX.eye(n)))
        return qdd, -solved[:, :n], -solved[:, n:2 * n], solved[:, 2 * n:]

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
        fd = self._forward() if with_jacobians else ca.Function("fd", [s.q, s.qd, s.tau],
                                                                 [self.graphs.forward_dynamics()])
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
        return x_next[:n], x_next[n:], J[:, :2 * n], J[:, 2 * n:]
