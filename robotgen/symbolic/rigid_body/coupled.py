"""A tree's coupling q_joints = S q + c (robotgen.model.coupling) as SX maps between its joints
and its coordinates, applied around the algorithms, which work in the joints:

    q_joints = S q + c,  qd_joints = S qd,  qdd_joints = S qdd     (into them)
    tau = S^T tau_joints,  M = S^T M_joints S,  J = J_joints S      (out of them)

S has one entry per row, so each product is a sum over the joints a coordinate moves (in joint
order), each term scaled by its multiplier (a multiplier of 1 or -1 costs nothing). Without a
coupling every map returns its argument itself: an uncoupled tree's graphs are what they were.
"""

from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree


def _scaled(x: ca.SX, m: float) -> ca.SX:
    return x if m == 1.0 else -x if m == -1.0 else m * x


class CoupledCoordinates:
    """A tree's coordinates mapped into its joints and back: q_joints = S q + c, S^T tau, S^T M S, J S."""

    def __init__(self, tree: KinematicTree):
        self.coupling = tree.coupling
        self.n_joints = tree.n_joints

    @property
    def coupled(self) -> bool:
        """Whether mimic joints couple the joints (else every map is the identity)."""
        return self.coupling is not None

    def positions(self, q: ca.SX) -> ca.SX:
        """q_joints = S q + c."""
        c = self.coupling
        if c is None:
            return q
        rows = []
        for i in range(self.n_joints):
            x = _scaled(q[c.coordinate[i]], c.multiplier[i])
            rows.append(x if c.offset[i] == 0.0 else x + c.offset[i])
        return ca.vertcat(*rows)

    def rates(self, qd: ca.SX) -> ca.SX:
        """qd_joints = S qd (and qdd_joints = S qdd)."""
        c = self.coupling
        if c is None:
            return qd
        return ca.vertcat(*(_scaled(qd[c.coordinate[i]], c.multiplier[i]) for i in range(self.n_joints)))

    def _sum(self, k: int, term) -> ca.SX:
        """sum over the joints i of coordinate k of S_ik term(i), in joint order."""
        c = self.coupling
        if c is None:
            raise TypeError("a sum over coupled joints needs the coupling")
        terms = [_scaled(term(i), c.multiplier[i]) for i in c.joints_of(k)]  # (every coordinate moves a joint)
        total = terms[0]
        for x in terms[1:]:
            total = total + x
        return total

    def forces(self, tau: ca.SX) -> ca.SX:
        """S^T tau_joints: a joint force vector (or the rows of a matrix) as coordinate forces."""
        c = self.coupling
        if c is None:
            return tau
        return ca.vertcat(*(self._sum(k, lambda i: tau[i, :]) for k in range(c.nq)))

    def columns(self, J: ca.SX) -> ca.SX:
        """J_joints S: a matrix's joint columns as coordinate columns."""
        c = self.coupling
        if c is None:
            return J
        return ca.horzcat(*(self._sum(k, lambda i: J[:, i]) for k in range(c.nq)))

    def matrix(self, M: ca.SX, symmetric: bool = False) -> ca.SX:
        """S^T M S; ``symmetric``: M is, and so is the result to the bit (the upper triangle
        mirrored)."""
        if self.coupling is None:
            return M
        R = self.forces(self.columns(M))
        if symmetric:
            n = R.shape[0]
            for a in range(n):
                for b in range(a + 1, n):
                    R[b, a] = R[a, b]
        return R
