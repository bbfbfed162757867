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
        self.inverse = self._positions_down(g, self.x_sym)  # Theta from root positions, or None

    @staticmethod
    def _positions_down(g: TreeGraphs, x: ca.SX) -> ca.SX | None:
        """Leaf positions from root positions through every ATTACH's h^-1, if all have one."""
        out: dict[str, ca.SX] = {}

        def down(name: str, pos: ca.SX) -> bool:
            node = g.system.nodes[name]
            graph = g.graph(name)
            if graph.attach is None:
                out[name] = pos
                return True
            if graph.attach.h_inverse is None:
                return False
            y = graph.attach.h_inverse(pos)
            row = 0
            for r in node.robots:
                ne = g.graph(r).sig.n_external
                if not down(r, rows(y, row, row + ne)):
                    return False
                row += ne
            return True

        if not down(g.system.root, x):
            return None
        return ca.vertcat(*[out[leaf] for leaf in g.leaves])


def leaf_velocities(g: TreeGraphs, v: ca.SX) -> ca.SX:
    """Leaf joint rates for root velocity v: w = A v at each ATTACH, down to the leaves (the
    tree's velocity map, linear in v; also what a resolved-rate controller of a composite
    robot resolves its command through, robotgen.symbolic.tree_rate_control)."""
    out: dict[str, ca.SX] = {}

    def down(name: str, vel: ca.SX) -> None:
        node = g.system.nodes[name]
        graph = g.graph(name)
        if graph.attach is None:
            out[name] = vel
            return
        w = graph.attach.A @ vel
        row = 0
        for r in node.robots:
            nv = g.graph(r).sig.n_velocity
            down(r, rows(w, row, row + nv))
            row += nv

    down(g.system.root, v)
    return ca.vertcat(*[out[leaf] for leaf in g.leaves])
