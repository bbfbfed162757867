"""Every node of a robot tree as CasADi graphs of the sensed leaf state (Theta, Theta_dot):
its position x and velocity v in its own coordinates (rd, eqs 3.7, 5.10-5.12), its
attributes M, C, N (DEFINE §3.2, ATTACH eqs 3.4-3.6, CONTROL §3.4), and for ATTACH the
maps that carry a written trajectory down (eqs 3.8, 5.3, 5.8-5.9).

The attributes are evaluated at the current configuration, as the paper does for all its
control laws (§5.2, last paragraph)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robotgen.model import exact
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    FRAME_CHANGE,
    PD,
    PLANAR_CONTACTS,
    POINT_CONTACTS,
    AttachNode,
    ControlNode,
    DefineNode,
    RobotSystem,
)
from robotgen.model.signature import Signature, robot_leaves, signature
from robotgen.symbolic.formula_graphs import expression_column, expression_map, expression_matrix
from robotgen.symbolic.leaf_attributes import LeafAttributes, leaf_attributes, rpy_rate_map, rpy_rotation
from robotgen.symbolic.spatial import skew
from robotgen.symbolic.nullspace import block_null_rows, gram_schmidt, null_rows
from robotgen.symbolic.rows import rows


@dataclass(eq=False)
class AttachMaps:
    """What ATTACH needs to write down: children velocities w = A v (children in order, each
    [external; internal]), Adot, the force map D [F_e; F_m1; F_i1] -> children external
    forces (J^T G^+, K^T, J^T H^T: eqs 5.3, 5.9), and h^-1 if known."""

    A: ca.SX
    Adot: ca.SX
    D: ca.SX
    h_inverse: Callable[[ca.SX], ca.SX] | None
    n_created_motions: int
    n_created_forces: int
    J: ca.SX  # constraint rows x robot coordinates (eq 3.2)
    H: ca.SX  # internal-force rows, orthonormal, spanning null(G) (eq 2.4)


@dataclass(eq=False)
class NodeGraph:
    name: str
    sig: Signature
    x: ca.SX  # external positions
    v: ca.SX  # velocity, [external; internal motions]
    M: ca.SX
    C: ca.SX
    N: ca.SX
    leaf: LeafAttributes | None = None
    attach: AttachMaps | None = None


def _blockdiag(blocks: list[ca.SX]) -> ca.SX:
    return ca.diagcat(*blocks) if blocks else ca.SX(0, 0)


def _pad(X: ca.SX, n: int) -> ca.SX:
    """Embed a k x k (or k x 1) attribute in the top-left of an n-dimensional one."""
    k = X.shape[0]
    if X.shape[1] == 1:
        return ca.vertcat(X, ca.SX.zeros(n - k, 1))
    return ca.blockcat([[X, ca.SX.zeros(k, n - k)], [ca.SX.zeros(n - k, k), ca.SX.zeros(n - k, n - k)]])


def _stacked_map(maps: list[Callable[[ca.SX], ca.SX]], sizes: list[int]) -> Callable[[ca.SX], ca.SX]:
    """Apply each map to its own consecutive slice of the input and stack the results."""
    offsets = np.cumsum([0] + sizes).tolist()
    return lambda x: ca.vertcat(*[f(rows(x, a, b)) for f, a, b in zip(maps, offsets, offsets[1:])])


def _rot2(psi: ca.SX) -> ca.SX:
    c, s = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))


class TreeGraphs:
    """Graphs of every node below the root, built once each from shared symbols."""

    def __init__(self, system: RobotSystem):
        self.system = system
        self.leaves = robot_leaves(system)
        sizes = [system.nodes[n].leaf.nq for n in self.leaves]
        self.offsets = dict(zip(self.leaves, np.cumsum([0] + sizes[:-1]).tolist()))
        self.sizes = dict(zip(self.leaves, sizes))
        self.n = int(sum(sizes))
        self.theta = ca.SX.sym("theta", self.n)
        self.theta_dot = ca.SX.sym("theta_dot", self.n)
        self._graphs: dict[str, NodeGraph] = {}

    def leaf_slice(self, name: str) -> slice:
        o = self.offsets[name]
        return slice(o, o + self.sizes[name])

    def graph(self, name: str) -> NodeGraph:
        if name not in self._graphs:
            node = self.system.nodes[name]
            if isinstance(node, DefineNode):
                self._graphs[name] = self._define(node)
            elif isinstance(node, ControlNode):
                self._graphs[name] = self._control(node)
            else:
                self._graphs[name] = self._attach(node)
        return self._graphs[name]

    def underlying_leaf(self, name: str) -> NodeGraph:
        node = self.system.nodes[name]
        while isinstance(node, ControlNode):
            node = self.system.nodes[node.robot]
        return self.graph(node.name)

    # -- DEFINE ----------------------------------------------------------------------
    def _define(self, node: DefineNode) -> NodeGraph:
        s = self.leaf_slice(node.name)
        q, qd = self.theta[s], self.theta_dot[s]
        attrs = leaf_attributes(node.leaf, q, qd)
        return NodeGraph(node.name, signature(self.system, node.name), q, qd, attrs.M, attrs.C, attrs.N, leaf=attrs)

    # -- CONTROL ---------------------------------------------------------------------
    def _control(self, node: ControlNode) -> NodeGraph:
        child = self.graph(node.robot)
        sig = signature(self.system, node.name)
        v = rows(child.v, 0, sig.n_velocity)  # resolved internal motions are the trailing ones
        n = sig.n_velocity
        if node.law == PD:  # a stiffness: the robot's dynamics pass through
            return NodeGraph(node.name, sig, child.x, v, child.M, child.C, child.N)
        return NodeGraph(node.name, sig, child.x, v, ca.SX.zeros(n, n), ca.SX.zeros(n, n), ca.SX.zeros(n, 1))

    # -- ATTACH ----------------------------------------------------------------------
    def _attach(self, node: AttachNode) -> NodeGraph:
        sig = signature(self.system, node.name)
        kids = [self.graph(r) for r in node.robots]
        y = ca.vertcat(*[k.x for k in kids])
        w_e = ca.vertcat(*[rows(k.v, 0, k.sig.n_external) for k in kids])
        w_i = ca.vertcat(*[rows(k.v, k.sig.n_external) for k in kids])
        m = y.shape[0]
        x, J, G, h_inverse, K, H = self._constraint(node, kids, y)
        n_rows, n = J.shape[0], sig.n_external
        if K is None:
            K = null_rows(J) if m > n_rows else ca.SX(0, m)
        if H is None:
            H = null_rows(G) if G.shape[1] > n else ca.SX(0, G.shape[1])
        GGt = G @ G.T
        G_pinv = ca.solve(GGt, G).T  # G^+ = G^T (G G^T)^-1, by a solve (rows x n)
        # J^-1 G^T (J square) or J^+ G^T = J^T (J J^T)^-1 G^T (eq 5.9), by solves
        J_pinv_Gt = J.T @ ca.solve(J @ J.T, G.T) if m > n_rows else ca.solve(J, G.T)
        n_m1, n_m2 = K.shape[0], w_i.shape[0]

        # rd: velocities in node coordinates (eqs 3.7, 5.11-5.12)
        xd_e = ca.solve(GGt, G @ (J @ w_e))
        v = ca.vertcat(xd_e, K @ w_e, w_i)
        n_vel = v.shape[0]

        # A: children velocities from node velocity (eqs 3.3, 5.8-5.9), rows in children order
        A_ext = ca.horzcat(J_pinv_Gt, K.T, ca.SX.zeros(m, n_m2))
        A_int = ca.horzcat(ca.SX.zeros(n_m2, n + n_m1), ca.SX.eye(n_m2))
        blocks, e0, i0 = [], 0, 0
        for k in kids:
            ne, ni = k.sig.n_external, k.sig.n_velocity - k.sig.n_external
            blocks += [A_ext[e0:e0 + ne, :], A_int[i0:i0 + ni, :]]
            e0, i0 = e0 + ne, i0 + ni
        A = ca.vertcat(*blocks)
        Adot = ca.jtimes(A, self.theta, self.theta_dot)

        # eqs 3.4-3.6, the payload's attributes at x, xd
        M_R = _blockdiag([k.M for k in kids])
        C_R = _blockdiag([k.C for k in kids])
        N_R = ca.vertcat(*[k.N for k in kids])
        Mp, Cp, Np = self._payload(node, x, xd_e)
        M = _pad(Mp, n_vel) + A.T @ M_R @ A
        C = _pad(Cp, n_vel) + A.T @ C_R @ A + A.T @ M_R @ Adot
        N = _pad(Np, n_vel) + A.T @ N_R

        D = ca.horzcat(J.T @ G_pinv, K.T, J.T @ H.T)
        maps = AttachMaps(A, Adot, D, h_inverse, n_m1, H.shape[0], J, H)
        return NodeGraph(node.name, sig, x, v, M, C, N, attach=maps)

    def _payload(self, node: AttachNode, x: ca.SX, xd: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        n = x.shape[0]
        if not node.payload:
            return ca.SX.zeros(n, n), ca.SX.zeros(n, n), ca.SX.zeros(n, 1)
        q, qd = ca.SX.sym("xp", n), ca.SX.sym("xdp", n)
        a = leaf_attributes(self.system.nodes[node.payload].leaf, q, qd)
        M, C, N = ca.substitute([a.M, a.C, a.N], [q, qd], [x, xd])
        return M, C, N

    @staticmethod
    def _point_contacts(pts: np.ndarray, y: ca.SX, m: int):
        """Fingertips held at body points c_k of a spatial payload, x = (p, rpy). The pose
        comes from the first three contacts: the triad they span in the body frame and the
        one their fingertips span in the world give R; p = p_1 - R c_1. A fingertip force f_k
        acts on (p, rpy) as (f_k, E^T (R c_k) x f_k), the columns of G."""
        def triad(a, b, c, lib):
            u, w = b - a, c - a
            e1 = u / lib.norm_2(u)
            e3 = lib.cross(u, w)
            e3 = e3 / lib.norm_2(e3)
            return lib.horzcat(e1, lib.cross(e3, e1), e3)

        body = np.array(ca.DM(triad(*(ca.DM(p) for p in pts[:3]), ca)))
        P = [y[3 * k:3 * k + 3] for k in range(3)]
        R = triad(*P, ca) @ body.T
        p = P[0] - R @ ca.DM(pts[0])
        rpy = ca.vertcat(ca.atan2(R[2, 1], R[2, 2]), ca.atan2(-R[2, 0], ca.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2)),
                         ca.atan2(R[1, 0], R[0, 0]))
        x = ca.vertcat(p, rpy)

        def h_inverse(xe: ca.SX) -> ca.SX:
            Re = rpy_rotation(rows(xe, 3, 6))
            return ca.vertcat(*[rows(xe, 0, 3) + Re @ ca.DM(c) for c in pts])

        Rx, E = rpy_rotation(rpy), rpy_rate_map(rpy)
        G = ca.horzcat(*[ca.vertcat(ca.SX.eye(3), E.T @ skew(Rx @ ca.DM(c))) for c in pts])
        H = None
        if len(pts) == 3:  # squeezes along the lines between contact pairs span null(G)
            squeezes = []
            for i, j in ((0, 1), (0, 2), (1, 2)):
                u = Rx @ ca.DM(exact.unit(pts[j] - pts[i]))
                parts = [ca.SX.zeros(3, 1)] * 3
                parts[i], parts[j] = u, -u
                squeezes.append(ca.vertcat(*parts))
            H = gram_schmidt(squeezes)
        return x, ca.SX.eye(m), G, h_inverse, None, H

    def _constraint(self, node: AttachNode, kids: list[NodeGraph], y: ca.SX):
        """x = h(y), J, G, h^-1, and where the constraint fixes them, the null bases K of J
        (frame changes: block by block) and H of G (two contacts: the squeeze)."""
        c = node.constraint
        m = y.shape[0]
        if c.kind == FRAME_CHANGE:
            leaves = [self.underlying_leaf(r) for r in node.robots]
            outs = [lf.leaf.kinematics(c.output) for lf in leaves]
            x = ca.vertcat(*outs)
            J = ca.jacobian(x, y)
            K = block_null_rows(J, [o.shape[0] for o in outs], [k.sig.n_external for k in kids])
            inverses = [lf.leaf.inverse_kinematics for lf in leaves]
            h_inverse = _stacked_map(inverses, [o.shape[0] for o in outs]) if all(inverses) else None
            return x, J, ca.SX.eye(x.shape[0]), h_inverse, K, None
        if c.kind == PLANAR_CONTACTS:
            pts = np.asarray(c.contacts, dtype=float)
            p1, p2 = y[0:2], y[2:4]
            d = p2 - p1
            psi = ca.atan2(d[1], d[0]) - exact.atan2(pts[1][1] - pts[0][1], pts[1][0] - pts[0][0])
            pos = p1 - _rot2(psi) @ ca.DM(pts[0])
            x = ca.vertcat(pos, psi)

            def h_inverse(xe: ca.SX) -> ca.SX:
                R = _rot2(xe[2])
                return ca.vertcat(*[xe[:2] + R @ ca.DM(p) for p in pts])

            cols = []
            R = _rot2(psi)
            for p in pts:
                r = R @ ca.DM(p)  # contact point relative to the centre, base frame
                cols += [ca.vertcat(1, 0, -r[1]), ca.vertcat(0, 1, r[0])]
            H = None
            if len(pts) == 2:  # positive internal force = squeeze: tip 1 pushes toward tip 2
                u = R @ ca.DM(exact.unit(pts[1] - pts[0]))
                H = ca.horzcat(u.T, -u.T) / exact.sqrt(2.0)
            return x, ca.SX.eye(m), ca.horzcat(*cols), h_inverse, None, H
        if c.kind == POINT_CONTACTS:
            return self._point_contacts(np.asarray(c.contacts, dtype=float), y, m)
        if c.kind == CONSTRAINT_FORMULAS:
            env: dict[str, object] = dict(c.parameters)
            names = [nm for k in kids for nm in k.sig.external]
            env.update({nm: y[i] for i, nm in enumerate(names)})
            x = expression_column(c.h, env)
            env.update({nm: x[i] for i, nm in enumerate(c.coordinates)})
            J = expression_matrix(c.J, env) if c.J is not None else ca.SX.eye(m)
            G = expression_matrix(c.G, env)
            h_inverse = expression_map(c.h_inverse, c.coordinates, c.parameters) if c.h_inverse else None
            return x, J, G, h_inverse, None, None
        raise ValueError(f"unknown constraint kind {c.kind}")
