"""The true constrained plant of a robot tree: its uncontrolled composite dynamics
(Deno et al. 1990, eq 2.3) in the root's velocity coordinates v, with the sensed leaf
state carried along: Theta_dot = A(Theta) v, M~ vdot + C~ v + N~ = A^T tau."""

from __future__ import annotations

import dataclasses

import casadi as ca

from robotgen.model.signature import constraint_residual_names, has_position_inverse, robot_leaves
from robotgen.model.system import AttachNode, ControlNode, Node, RobotSystem
from robotgen.symbolic.kernel import NO_PARAMETERS, ParameterSymbols
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rows import rows
from robotgen.symbolic.system import SystemGraphs


def strip_controls(system: RobotSystem) -> RobotSystem:
    """The same tree with every CONTROL node replaced by the robot it controls."""

    def through(name: str) -> str:
        while isinstance(system.nodes[name], ControlNode):
            name = system.control(name).robot
        return name

    nodes: dict[str, Node] = {}
    for name, node in system.nodes.items():
        if isinstance(node, ControlNode):
            continue
        if isinstance(node, AttachNode):
            node = dataclasses.replace(node, robots=tuple(through(r) for r in node.robots))
        nodes[name] = node
    return dataclasses.replace(system, nodes=nodes, root=through(system.root))


class Plant:
    """The true constrained plant of a system: its velocity v and the leaves' dynamics under the constraints."""

    def __init__(self, system: RobotSystem, parameters: ParameterSymbols = NO_PARAMETERS):
        """``parameters``: the module's run-time parameters (a payload's mass, if run-time,
        is read from them as the controller's graphs read it)."""
        self.graphs = SystemGraphs(strip_controls(system), parameters)
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
        self.residual = constraint_residual(g)
        self.residual_names = constraint_residual_names(g.system)
        self.internal_forces = internal_forces(g, self.v, self.v_dot, leaf_v, self.tau)


def sensed_forces(plant: Plant) -> ca.SX:
    """What each leaf exerts on what it holds, in its own coordinates: tau_sensed = tau -
    (M theta_ddot + C theta_dot + N) of the leaf alone, = J^T lambda summed over the
    constraints it acts through (a fingertip force sensor's reading carried to the joints).
    The leaf rates and accelerations are the plant's: theta_dot = A v and theta_ddot = A vdot
    + (d theta_dot / d theta) theta_dot. Functions of (theta, v, tau); the servo step's
    tau_sensed (robotgen.symbolic.servo, rd's force term, eq 3.7)."""
    g = plant.graphs
    leaf_v = plant.theta_dot
    theta_ddot = ca.jtimes(leaf_v, g.theta, leaf_v) + ca.jacobian(leaf_v, plant.v) @ plant.v_dot
    parts = []
    for leaf in g.leaves:
        lg, s = g.graph(leaf), g.leaf_slice(leaf)
        own = lg.M @ theta_ddot[s] + lg.C @ lg.v + lg.N
        parts.append(plant.tau[s] - ca.substitute(own, g.theta_dot, leaf_v))
    return ca.vertcat(*parts)


def constraint_residual(g: SystemGraphs) -> ca.SX:
    """y - h^-1(h(y)) at every ATTACH that has h^-1, y its robots' stacked positions: zero
    exactly when the sensed leaf positions satisfy every position-level constraint (a
    grasp's fingertips at the contact points). Entries: constraint_residual_names."""
    parts = []
    for node in g.system.walk():
        if isinstance(node, AttachNode) and has_position_inverse(g.system, node):
            graph = g.graph(node.name)
            y = ca.vertcat(*[g.graph(r).x for r in node.robots])
            maps = graph.attach
            if maps is None or maps.h_inverse is None:  # has_position_inverse says it has one
                raise TypeError(f"attach '{node.name}' has no position inverse")
            parts.append(y - maps.h_inverse(graph.x))
    return ca.vertcat(*parts) if parts else ca.SX(0, 1)


def internal_forces(g: SystemGraphs, v: ca.SX, v_dot: ca.SX, leaf_v: ca.SX, tau: ca.SX) -> ca.SX:
    """The internal forces the grasps actually carry (eq 2.4): at every ATTACH that creates
    internal forces (walk order), f = H lambda, lambda the force its robots exert on the
    constraint, from their own dynamics: J^T lambda = F_c - (M_c wdot + C_c w + N_c) on their
    external coordinates, F_c = A_c^T tau the actuators' force on them (A_c: the robot's
    velocity to its leaves' rates). w, wdot flow down from the root: w = A v, wdot = A vdot
    + Adot v (eq 3.8). Functions of (theta, v, tau), with vdot the plant's."""

    def on_plant(x: ca.SX) -> ca.SX:  # sensed rates are the plant's
        return ca.substitute(x, g.theta_dot, leaf_v) if ca.depends_on(x, g.theta_dot) else x

    parts: list[ca.SX] = []

    def down(name: str, vel: ca.SX, acc: ca.SX) -> None:
        graph = g.graph(name)
        maps = graph.attach
        if maps is None:
            return
        w = maps.A @ vel
        wdot = maps.A @ acc + on_plant(maps.Adot) @ vel
        row, rho = 0, []
        for r in g.system.attach(name).robots:
            child = g.graph(r)
            n = child.sig.n_velocity
            w_c, wdot_c = rows(w, row, row + n), rows(wdot, row, row + n)
            u = ca.SX.sym(f"u_{r}", n)
            leaves = robot_leaves(g.system, r)
            all_rates = _down_from(g, r, u)
            A_c = ca.jacobian(ca.vertcat(*[all_rates[g.leaf_slice(leaf)] for leaf in leaves]), u)
            tau_c = ca.vertcat(*[tau[g.leaf_slice(leaf)] for leaf in leaves])
            F_c = A_c.T @ tau_c
            own = on_plant(child.M) @ wdot_c + on_plant(child.C) @ w_c + on_plant(child.N)
            rho.append(rows(F_c - own, 0, child.sig.n_external))
            down(r, w_c, wdot_c)
            row += n
        if maps.n_created_forces:
            J, stacked = maps.J, ca.vertcat(*rho)
            lam = ca.solve(J @ J.T, J @ stacked)  # J^T lambda = rho (J has full row rank)
            parts.append(maps.H @ lam)

    down(g.system.root, v, v_dot)
    return ca.vertcat(*parts) if parts else ca.SX(0, 1)


def _down_from(g: SystemGraphs, name: str, vel: ca.SX) -> ca.SX:
    """Leaf rates (all leaves, in leaf order; zero outside ``name``'s subtree) for velocity
    ``vel`` of node ``name``."""
    out = {leaf: ca.SX.zeros(g.sizes[leaf]) for leaf in g.leaves}

    def down(node: str, val: ca.SX) -> None:
        graph = g.graph(node)
        if graph.attach is None:
            out[node] = val
            return
        w = graph.attach.A @ val
        row = 0
        for r in g.system.attach(node).robots:
            n = g.graph(r).sig.n_velocity
            down(r, rows(w, row, row + n))
            row += n

    down(name, vel)
    return ca.vertcat(*[out[leaf] for leaf in g.leaves])


def _to_leaves(g: SystemGraphs, value: ca.SX, step, share) -> ca.SX | None:
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
        for r in g.system.attach(name).robots:
            n = share(g.graph(r).sig)
            if not down(r, rows(stacked, row, row + n)):
                return False
            row += n
        return True

    return ca.vertcat(*[out[leaf] for leaf in g.leaves]) if down(g.system.root, value) else None


def leaf_velocities(g: SystemGraphs, v: ca.SX) -> ca.SX:
    """Leaf joint rates for root velocity v: w = A v at each ATTACH, down to the leaves (the
    tree's velocity map, linear in v; also what a resolved-rate controller of a composite
    robot resolves its command through, robotgen.symbolic.root_laws.resolved_rate.composite)."""
    rates = _to_leaves(g, v, lambda maps, vel: maps.A @ vel, lambda sig: sig.n_velocity)
    if rates is None:  # (A v exists at every ATTACH)
        raise TypeError("a velocity map is missing")
    return rates


def leaf_positions(g: SystemGraphs, x: ca.SX) -> ca.SX | None:
    """Leaf positions from root positions through every ATTACH's h^-1, if all have one."""
    return _to_leaves(
        g, x, lambda maps, pos: maps.h_inverse(pos) if maps.h_inverse else None, lambda sig: sig.n_external
    )
