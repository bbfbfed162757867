"""ATTACH (Deno et al. 1990, §3.3): robots joined to a payload through a constraint
J(y) ydot = G^T(x) xdot (eq 3.2), as CasADi graphs.

- the node's coordinates x = h(y) and velocity (rd, eqs 3.7, 5.10-5.12);
- its composite attributes M = Mp + A^T M_R A, C = Cp + A^T (C_R A + M_R Adot),
  N = Np + A^T N_R (eqs 3.4-3.6), A the map from node to robot velocities (eqs 3.3,
  5.8-5.9);
- the grasp maps: G^+ for external forces, H spanning null(G) (internal forces, eqs 2.4,
  5.2-5.5), K spanning null(J) (internal motions, eqs 2.5, 5.6-5.9);
- h^-1 where the constraint gives one (positions flow down through it).

Constraints: frame_change (nil payload, G = I, x the robots' kinematic outputs),
planar_contacts and point_contacts (fingertips at points of a rigid payload, G from the
contact geometry), and the user's formulas for h, h^-1, J, G."""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from robotgen.model.signature import Signature
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    FRAME_CHANGE,
    PLANAR_CONTACTS,
    POINT_CONTACTS,
    AttachNode,
    Leaf,
)
from robotgen.numeric import exact
from robotgen.symbolic.define import leaf_attributes
from robotgen.symbolic.formulas import expression_column, expression_map, expression_matrix
from robotgen.symbolic.node import AttachMaps, NodeGraph
from robotgen.symbolic.nullspace import block_null_rows, gram_schmidt, null_rows
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rate_map, rpy_rotation
from robotgen.symbolic.rigid_body.spatial import skew
from robotgen.symbolic.rows import rows


def attach_graph(
    node: AttachNode,
    sig: Signature,
    kids: list[NodeGraph],
    leaves: list[NodeGraph],
    payload: Leaf | None,
    theta: ca.SX,
    theta_dot: ca.SX,
    payload_values: dict[str, ca.SX] | None = None,
) -> NodeGraph:
    """ATTACH's graphs from its robots' (``kids``, in order; ``leaves``: the leaf under each,
    through control nodes, for a frame change) and its payload's leaf; every graph a
    function of the sensed (theta, theta_dot)."""
    y = ca.vertcat(*[k.x for k in kids])
    w_e = ca.vertcat(*[rows(k.v, 0, k.sig.n_external) for k in kids])
    w_i = ca.vertcat(*[rows(k.v, k.sig.n_external) for k in kids])
    m = y.shape[0]
    x, J, G, h_inverse, K, H = _constraint(node, kids, leaves, y)
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
        blocks += [A_ext[e0 : e0 + ne, :], A_int[i0 : i0 + ni, :]]
        e0, i0 = e0 + ne, i0 + ni
    A = ca.vertcat(*blocks)
    Adot = ca.jtimes(A, theta, theta_dot)

    # eqs 3.4-3.6, the payload's attributes at x, xd
    M_R = _blockdiag([k.M for k in kids])
    C_R = _blockdiag([k.C for k in kids])
    N_R = ca.vertcat(*[k.N for k in kids])
    Mp, Cp, Np = _payload(payload, x, xd_e, payload_values)
    M = _pad(Mp, n_vel) + A.T @ M_R @ A
    C = _pad(Cp, n_vel) + A.T @ C_R @ A + A.T @ M_R @ Adot
    N = _pad(Np, n_vel) + A.T @ N_R

    D = ca.horzcat(J.T @ G_pinv, K.T, J.T @ H.T)
    maps = AttachMaps(A, Adot, D, h_inverse, n_m1, H.shape[0], J, H)
    return NodeGraph(node.name, sig, x, v, M, C, N, attach=maps)


def _payload(payload: Leaf | None, x: ca.SX, xd: ca.SX, values: dict[str, ca.SX] | None) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The payload's DEFINE attributes at the node's positions and rates (nil: zero)."""
    n = x.shape[0]
    if payload is None:
        return ca.SX.zeros(n, n), ca.SX.zeros(n, n), ca.SX.zeros(n, 1)
    q, qd = ca.SX.sym("xp", n), ca.SX.sym("xdp", n)
    a = leaf_attributes(payload, q, qd, values)
    M, C, N = ca.substitute([a.M, a.C, a.N], [q, qd], [x, xd])
    return M, C, N


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

    c1, c2, c3 = (ca.DM(p) for p in pts[:3])
    body = np.array(ca.DM(triad(c1, c2, c3, ca)))
    P = [y[3 * k : 3 * k + 3] for k in range(3)]
    R = triad(P[0], P[1], P[2], ca) @ body.T
    p = P[0] - R @ ca.DM(pts[0])
    rpy = rpy_of(R)
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


def _kinematics(graph: NodeGraph) -> Callable[[str], ca.SX]:
    """A frame change's robot's kinematic outputs (the front end refuses a robot without them)."""
    if graph.leaf is None or graph.leaf.kinematics is None:
        raise TypeError(f"'{graph.name}' has no kinematic outputs")
    return graph.leaf.kinematics


def _constraint(node: AttachNode, kids: list[NodeGraph], leaves: list[NodeGraph], y: ca.SX):
    """x = h(y), J, G, h^-1, and where the constraint fixes them, the null bases K of J
    (frame changes: block by block) and H of G (two contacts: the squeeze)."""
    c = node.constraint
    m = y.shape[0]
    if c.kind == FRAME_CHANGE:
        outs = [_kinematics(lf)(c.output) for lf in leaves]
        x = ca.vertcat(*outs)
        J = ca.jacobian(x, y)
        K = block_null_rows(J, [o.shape[0] for o in outs], [k.sig.n_external for k in kids])
        inverses = [lf.leaf.inverse_kinematics for lf in leaves if lf.leaf is not None]
        known = [inverse for inverse in inverses if inverse is not None]
        h_inverse = _stacked_map(known, [o.shape[0] for o in outs]) if len(known) == len(leaves) else None
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
        return _point_contacts(np.asarray(c.contacts, dtype=float), y, m)
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
