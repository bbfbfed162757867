"""The list of emitted functions for a robot system, each a CasADi Function with ports."""
from __future__ import annotations

import casadi as ca

from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.system import RobotSystem
from robotgen.symbolic.chain_graphs import ChainGraphs, Symbols
from robotgen.symbolic.formula_graphs import FormulaGraphs
from robotgen.symbolic.kernel import Kernel, Port

# name: (inputs, output shape as a function of nq, doc)
_CHAIN = {
    "fk": ("q", (4, 4), "Homogeneous transform of the tip frame in the base frame."),
    "jacobian": ("q", (6, "n"), "Geometric Jacobian [v; omega] of the tip frame origin, base "
                 "coordinates (Whitney 1972, eqs 8-9)."),
    "jacobian_hand": ("q", (6, "n"), "Geometric Jacobian in tip-frame coordinates (Whitney 1972, eq 7)."),
    "jacobian_dot_qd": ("q qd", (6, 1), "Jdot(q, qd) qd: tip acceleration at qdd = 0."),
    "mass": ("q", ("n", "n"), "Joint-space inertia matrix M(q) (composite rigid bodies + armature)."),
    "coriolis": ("q qd", ("n", "n"), "Coriolis matrix C(q, qd) from Christoffel symbols; "
                 "Mdot - 2C is skew-symmetric."),
    "gravity": ("q", ("n", 1), "Gravity torques g(q)."),
    "nonlinear": ("q qd", ("n", 1), "C(q, qd) qd + N(q, qd): Coriolis, centrifugal, gravity, friction."),
    "inverse_dynamics": ("q qd qdd", ("n", 1), "Joint torques M qdd + C qd + N (recursive Newton-Euler)."),
    "forward_dynamics": ("q qd tau", ("n", 1), "Joint accelerations M^-1 (tau - C qd - N) by Cholesky solve."),
}

_FORMULA = {
    "mass": ("q", ("n", "n"), "Inertia matrix M(q) as given in the spec."),
    "coriolis": ("q qd", ("n", "n"), "Coriolis matrix C(q, qd) (given, or Christoffel symbols of M)."),
    "gravity": ("q", ("n", 1), "N(q, 0)."),
    "nonlinear": ("q qd", ("n", 1), "C(q, qd) qd + N(q, qd)."),
    "inverse_dynamics": ("q qd qdd", ("n", 1), "M qdd + C qd + N."),
    "forward_dynamics": ("q qd tau", ("n", 1), "M^-1 (tau - C qd - N) by Cholesky solve."),
    "kinematics": ("q", ("k", 1), "Output map x = f(q) as given in the spec."),
    "kinematics_jacobian": ("q", ("k", "n"), "df/dq."),
}


def _row_major(X: ca.SX) -> ca.SX:
    return ca.densify(ca.reshape(X.T, X.numel(), 1))


def _kernel(name: str, doc: str, inputs: str, shape: tuple[int, int], expr: ca.SX,
            sym: Symbols, n: int, prefix: str = "") -> Kernel:
    ports = tuple(Port(s, n) for s in inputs.split())
    args = [getattr(sym, s) for s in inputs.split()]
    assert expr.shape == shape, (name, expr.shape, shape)
    fname = prefix + name
    f = ca.Function(fname, args, [_row_major(expr)], list(inputs.split()), [name], {"cse": True})
    return Kernel(fname, doc, ports, (Port(name, *shape),), f)


def _resolve(shape, n: int, k: int) -> tuple[int, int]:
    return tuple({"n": n, "k": k}.get(d, d) for d in shape)


def leaf_kernels(leaf: KinematicTree | FormulaRobot, prefix: str = "") -> list[Kernel]:
    n = leaf.nq
    sym = Symbols.make(n)
    if isinstance(leaf, KinematicTree):
        graphs, table, k = ChainGraphs(leaf, sym), _CHAIN, 0
    else:
        graphs, table = FormulaGraphs(leaf, sym), dict(_FORMULA)
        k = len(leaf.kinematics or ())
        if not k:
            del table["kinematics"], table["kinematics_jacobian"]
    kernels = [
        _kernel(name, doc, inputs, _resolve(shape, n, k), getattr(graphs, name)(), sym, n, prefix)
        for name, (inputs, shape, doc) in table.items()
    ]
    if isinstance(leaf, KinematicTree):
        kernels.append(_servo_terms(graphs, sym, n, prefix))
    return kernels


def _servo_terms(graphs: ChainGraphs, sym: Symbols, n: int, prefix: str) -> Kernel:
    """What one computed-torque cycle needs, in one call sharing sin/cos and kinematics."""
    outputs = [("mass", graphs.mass(), (n, n)), ("nonlinear", graphs.nonlinear(), (n, 1)),
               ("jacobian", graphs.jacobian(), (6, n)), ("jacobian_dot_qd", graphs.jacobian_dot_qd(), (6, 1))]
    name = prefix + "servo_terms"
    f = ca.Function(name, [sym.q, sym.qd], [_row_major(e) for _, e, _ in outputs], ["q", "qd"],
                    [o for o, _, _ in outputs], {"cse": True})
    return Kernel(name, "M(q), C(q, qd) qd + N, the tip Jacobian J and Jdot qd in one call: a "
                  "computed-torque servo cycle's terms, sharing sin/cos and kinematics.",
                  (Port("q", n), Port("qd", n)), tuple(Port(o, *shape) for o, _, shape in outputs), f)


def kernels_for(system: RobotSystem) -> list[Kernel]:
    """A single leaf: its kernels under the contract's names. A resolved-rate controller of a
    chain: the chain's kernels plus the controller's steps (robotgen.symbolic.rate_control);
    of a composite robot: the robot tree's kernels plus the controller's steps
    (robotgen.symbolic.tree_rate_control). A tree: every node's attributes, rd and wr, the
    fused servo step and the plant (robotgen.symbolic.tree_kernels)."""
    if system.is_single_leaf:
        return leaf_kernels(system.root_node.leaf)
    if system.rate_controls_composite:
        from robotgen.symbolic.tree_rate_control import tree_rate_kernels

        return tree_rate_kernels(system)
    if system.is_rate_controlled:
        from robotgen.symbolic.rate_control import rate_control_kernels

        return rate_control_kernels(system)
    from robotgen.symbolic.tree_kernels import tree_kernels

    return tree_kernels(system)


def module_extras(system: RobotSystem) -> tuple[dict, dict]:
    """(extra info() and manifest keys, module attributes) worked out in the symbolic layer:
    a resolved-rate controller's settings and its regulator's gains and reports."""
    if system.rate_controls_composite:
        from robotgen.symbolic.tree_rate_control import tree_rate_report

        return tree_rate_report(system)
    if system.is_rate_controlled:
        from robotgen.symbolic.rate_control import rate_control_report

        return rate_control_report(system)
    return {}, {}
