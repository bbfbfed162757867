"""The true constrained plant of a robot tree: its uncontrolled composite dynamics
(Deno et al. 1990, eq 2.3) in the root's velocity coordinates v, with the sensed leaf
state carried along: Theta_dot = A(Theta) v, M~ vdot + C~ v + N~ = A^T tau."""
from __future__ import annotations

import dataclasses

import casadi as ca

from robotgen.model.system import AttachNode, ControlNode, RobotSystem
from robotgen.symbolic.cholesky import cholesky_solve
from robotgen.symbolic.rows import rows
from robotgen.symbolic.tree import TreeGraphs


def strip_controls(system: RobotSystem) -> RobotSystem:
    """The same tree with every CONTROL node replaced by the robot it controls."""

    def through(name: str) -> str:
        while isinstance(system.nodes[name], ControlNode):
            name = system.nodes[name].robot
        return name

    nodes = {}
    for name, node in system.nodes.items():
        if isinstance(node, ControlNode):
            continue
        if isinstance(node, AttachNode):
            node = dataclasses.replace(node, robots=tuple(through(r) for r in node.robots))
        nodes[name] = node
    return dataclasses.replace(system, nodes=nodes, root=through(system.root))


class Plant:
    def __init__(self, system: RobotSystem):
        self.graphs = TreeGraphs(strip_controls(system))
        g = self.graphs
        root = g.graph(g.system.root)
        self.n_v = root.sig.n_velocity
        self.v = ca.SX.sym("v", self.n_v)
        leaf_v = leaf_velocities(g, self.v)  # Theta_dot = A_total(Theta) v
        self.theta_dot = leaf_v
        A_total = ca.jacobian(leaf_v, self.v)
        self.tau = ca.SX.sym("tau", g.n)
        Cv_N = ca.substitute(root.C @ root.v + root.N, g.theta_dot, leaf_v)
        M = root.M
        self.v_dot = cholesky_solve(M, A_total.T @ self.tau - Cv_N)
        self.read_v = root.v  # v from a sensed (Theta, Theta_dot)
        self.x = root.x
        self.x_sym = ca.SX.sym("x", root.sig.n_external)
        self.inverse = leaf_positions(g, self.x_sym)  # Theta from root positions, or None


def _to_leaves(g: TreeGraphs, value: ca.SX, step, share) -> ca.SX | None:
    """Carry a root quantity down through every ATTACH to the leaves and stack it in leaf
    order. ``step(attach_maps, value)`` gives the robots' stacked values (None where it
    cannot), ``share(signature)`` each robot's length in them."""
    out: dict[str, ca.SX] = {}

    def down(name: str, val: ca.SX) -> bool:
        graph = g.graph(name)
        if graph.attach is None:
            out[name] = val
            return True
        stacked = step(graph.attach, val)
        if stacked is None:
            return False
        row = 0
        for r in g.system.nodes[name].robots:
            n = share(g.graph(r).sig)
            if not down(r, rows(stacked, row, row + n)):
                return False
            row += n
        return True

    return ca.vertcat(*[out[leaf] for leaf in g.leaves]) if down(g.system.root, value) else None


def leaf_velocities(g: TreeGraphs, v: ca.SX) -> ca.SX:
    """Leaf joint rates for root velocity v: w = A v at each ATTACH, down to the leaves (the
    tree's velocity map, linear in v; also what a resolved-rate controller of a composite
    robot resolves its command through, robotgen.symbolic.tree_rate_control)."""
    return _to_leaves(g, v, lambda maps, vel: maps.A @ vel, lambda sig: sig.n_velocity)


def leaf_positions(g: TreeGraphs, x: ca.SX) -> ca.SX | None:
    """Leaf positions from root positions through every ATTACH's h^-1, if all have one."""
    return _to_leaves(g, x, lambda maps, pos: maps.h_inverse(pos) if maps.h_inverse else None,
                      lambda sig: sig.n_external)
