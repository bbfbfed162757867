"""Every node of a robot system as CasADi graphs of the sensed leaf state (Theta, Theta_dot):
its position x and velocity v in its own coordinates (rd, eqs 3.7, 5.10-5.12) and its
attributes M, C, N, built once each, children first: DEFINE by robotgen.symbolic.define
(§3.2), ATTACH by robotgen.symbolic.attach (eqs 3.4-3.8), CONTROL by its law
(robotgen.symbolic.control, §3.4).

The attributes are evaluated at the current configuration, as the paper does for all its
control laws (§5.2, last paragraph)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from robotgen.model.formula import FormulaRobot
from robotgen.model.signature import robot_leaves, signature
from robotgen.model.system import (
    AttachNode,
    ControlNode,
    DefineNode,
    Leaf,
    PlanarBody,
    RobotSystem,
    SpatialBody,
    under_controls,
)
from robotgen.symbolic.attach import attach_graph
from robotgen.symbolic.control.tree_laws import tree_law
from robotgen.symbolic.define import leaf_attributes
from robotgen.symbolic.kernel import NO_PARAMETERS, ParameterSymbols
from robotgen.symbolic.node import NodeGraph
from robotgen.symbolic.rows import rows


class SystemGraphs:
    """Graphs of every node below the root, from shared symbols theta, theta_dot (the
    actuated leaves' joint states, stacked in tree order)."""

    def __init__(self, system: RobotSystem, parameters: ParameterSymbols = NO_PARAMETERS):
        self.system = system
        self.parameters = parameters
        self.leaves = robot_leaves(system)
        sizes = [system.leaf(n).nq for n in self.leaves]
        self.offsets = dict(zip(self.leaves, np.cumsum([0] + sizes[:-1]).tolist()))
        self.sizes = dict(zip(self.leaves, sizes))
        self.n = int(sum(sizes))
        self.theta = ca.SX.sym("theta", self.n)
        self.theta_dot = ca.SX.sym("theta_dot", self.n)
        self._graphs: dict[str, NodeGraph] = {}

    def leaf_slice(self, name: str) -> slice:
        """The slice of leaf ``name``'s coordinates in the stacked leaf vector."""
        o = self.offsets[name]
        return slice(o, o + self.sizes[name])

    def graph(self, name: str) -> NodeGraph:
        """The graphs of node ``name``, built once."""
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
        """The graphs of the leaf or ATTACH node below any controllers of ``name``."""
        return self.graph(under_controls(self.system.nodes, name).name)

    def _define(self, node: DefineNode) -> NodeGraph:
        s = self.leaf_slice(node.name)
        q, qd = self.theta[s], self.theta_dot[s]
        attrs = leaf_attributes(node.leaf, q, qd, leaf_values(self.parameters, node))
        return NodeGraph(node.name, signature(self.system, node.name), q, qd, attrs.M, attrs.C, attrs.N, leaf=attrs)

    def _control(self, node: ControlNode) -> NodeGraph:
        child = self.graph(node.robot)
        sig = signature(self.system, node.name)
        v = rows(child.v, 0, sig.n_velocity)  # resolved internal motions are the trailing ones
        M, C, N = tree_law(node.law).attributes(child, sig.n_velocity)
        return NodeGraph(node.name, sig, child.x, v, M, C, N)

    def _attach(self, node: AttachNode) -> NodeGraph:
        payload = self.system.define(node.payload) if node.payload else None
        return attach_graph(
            node,
            signature(self.system, node.name),
            [self.graph(r) for r in node.robots],
            [self.underlying_leaf(r) for r in node.robots],
            payload.leaf if payload else None,
            self.theta,
            self.theta_dot,
            leaf_values(self.parameters, payload) if payload else {},
        )


def leaf_values(parameters: ParameterSymbols, node: DefineNode) -> dict[str, ca.SX]:
    """A leaf's run-time parameters as symbols, by their name in the leaf."""
    return {key: parameters.symbols[f"{node.name}_{key}"] for key in _runtime(node.leaf)}


def _runtime(leaf: Leaf | None) -> frozenset[str]:
    """The names of a leaf's run-time parameters (a chain has none)."""
    return leaf.runtime if isinstance(leaf, (FormulaRobot, PlanarBody, SpatialBody)) else frozenset()
