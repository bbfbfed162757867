"""The functions of a module whose root is one leaf robot (DEFINE): a chain's fk, Jacobians,
M, C, N, inverse and forward dynamics and the fused servo terms, or a formulas leaf's M, C,
N and kinematics, each a CasADi Function with named ports."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import casadi as ca

from robotgen.model.chain import KinematicTree, joints_without_inertia
from robotgen.model.derivatives import SEMI_IMPLICIT_EULER, DerivativeSettings
from robotgen.model.formula import FormulaRobot
from robotgen.symbolic.dynamics_derivatives import DynamicsDerivatives
from robotgen.symbolic.formulas import FormulaGraphs
from robotgen.symbolic.kernel import NO_PARAMETERS, Kernel, Matrix, ParameterSymbols, Shape, make_kernel
from robotgen.symbolic.op_count import count_operations
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.chain_loops import (
    CORIOLIS_LOOPS_ABOVE_OPS,
    LOOPS_ABOVE_DOF,
    LOOPS_ABOVE_OPS,
    ChainLoops,
)
from robotgen.symbolic.schedule import ScheduleBuilder

# name: (inputs, output shape as a function of nq, doc)
_CHAIN = {
    "fk": ("q", (4, 4), "Homogeneous transform of the tip frame in the base frame."),
    "jacobian": (
        "q",
        (6, "n"),
        "Geometric Jacobian [v; omega] of the tip frame origin, base coordinates (Whitney 1972, eqs 8-9).",
    ),
    "jacobian_hand": ("q", (6, "n"), "Geometric Jacobian in tip-frame coordinates (Whitney 1972, eq 7)."),
    "jacobian_dot_qd": ("q qd", (6, 1), "Jdot(q, qd) qd: tip acceleration at qdd = 0."),
    "mass": ("q", ("n", "n"), "Joint-space inertia matrix M(q) (composite rigid bodies + armature)."),
    "coriolis": ("q qd", ("n", "n"), "Coriolis matrix C(q, qd) from Christoffel symbols; Mdot - 2C is skew-symmetric."),
    "gravity": ("q", ("n", 1), "Gravity torques g(q)."),
    "nonlinear": ("q qd", ("n", 1), "C(q, qd) qd + N(q, qd): Coriolis, centrifugal, gravity, friction."),
    "inverse_dynamics": ("q qd qdd", ("n", 1), "Joint torques M qdd + C qd + N (recursive Newton-Euler)."),
    "forward_dynamics": (
        "q qd tau",
        ("n", 1),
        "Joint accelerations M^-1 (tau - C qd - N) by an L D L^T solve (past 12 joints: articulated bodies).",
    ),
}

_FORMULA = {
    "mass": ("q", ("n", "n"), "Inertia matrix M(q) as given in the spec."),
    "coriolis": ("q qd", ("n", "n"), "Coriolis matrix C(q, qd) (given, or Christoffel symbols of M)."),
    "gravity": ("q", ("n", 1), "N(q, 0)."),
    "nonlinear": ("q qd", ("n", 1), "C(q, qd) qd + N(q, qd)."),
    "inverse_dynamics": ("q qd qdd", ("n", 1), "M qdd + C qd + N."),
    "forward_dynamics": ("q qd tau", ("n", 1), "M^-1 (tau - C qd - N) by an L D L^T solve."),
    "kinematics": ("q", ("k", 1), "Output map x = f(q) as given in the spec."),
    "kinematics_jacobian": ("q", ("k", "n"), "df/dq."),
}


GUARDED = frozenset({"forward_dynamics"})  # see Kernel.guarded; the derivative kernels below too


def _kernel(
    name: str,
    doc: str,
    inputs: str,
    shape: tuple[int, int],
    expr: ca.SX,
    sym: Symbols,
    prefix: str,
    parameters: ParameterSymbols,
) -> Kernel:
    return make_kernel(
        prefix + name,
        doc,
        [(s, getattr(sym, s)) for s in inputs.split()],
        [(name, expr, shape)],
        parameters,
        guarded=name in GUARDED,
    )


LOOPED = {  # the chain kernels ChainLoops builds: name -> how (gravity stays straight-line: O(n) and lean)
    "mass": lambda loops, b, sym: loops.mass(b),
    "nonlinear": lambda loops, b, sym: loops.inverse_dynamics(b, sym.qd, None),
    "inverse_dynamics": lambda loops, b, sym: loops.inverse_dynamics(b, sym.qd, sym.qdd),
    "coriolis": lambda loops, b, sym: loops.coriolis(b, sym.qd),
    "forward_dynamics": lambda loops, b, sym: loops.forward_dynamics(b, sym.qd, sym.tau),
}


def _long(symbols: list[ca.SX], outputs, n: int, above: int = LOOPS_ABOVE_OPS) -> bool:
    """Whether straight-line code would be long (more than ``above`` operations); past
    LOOPS_ABOVE_DOF joints it is, without building it to count."""
    return n > LOOPS_ABOVE_DOF or count_operations(symbols, outputs())["total"] > above


def _looped(
    loops: ChainLoops,
    name: str,
    doc: str,
    inputs: str,
    shape: tuple[int, int],
    expr,
    sym: Symbols,
    prefix: str,
    parameters: ParameterSymbols,
) -> Kernel | None:
    """The kernel as loops when it is one of LOOPED, the chain reads no run-time parameter
    and the kernel's straight-line form (``expr()``) would be long."""
    symbols = [getattr(sym, s) for s in inputs.split()]
    above = CORIOLIS_LOOPS_ABOVE_OPS if name == "coriolis" else LOOPS_ABOVE_OPS
    if name not in LOOPED or parameters.parameters or not _long(symbols, lambda: [expr()], loops.n, above):
        return None
    b = ScheduleBuilder(symbols, [shape[0] * shape[1]])
    LOOPED[name](loops, b, sym)
    return make_kernel(
        prefix + name,
        doc,
        [(s, getattr(sym, s)) for s in inputs.split()],
        [(name, None, shape)],
        guarded=name in GUARDED,
        schedule=b,
    )


def _resolve(shape, n: int, k: int) -> tuple[int, int]:
    """The table's shape for n coordinates and k outputs: a Matrix when its columns are not
    the literal 1, so that a one-coordinate robot's M is (1, 1) and J (6, 1)."""
    rows, cols = ({"n": n, "k": k}.get(d, d) for d in shape)
    return Matrix(rows, cols) if shape[1] != 1 else (rows, cols)


def leaf_kernels(
    leaf: KinematicTree | FormulaRobot,
    prefix: str = "",
    parameters: ParameterSymbols = NO_PARAMETERS,
    values: dict[str, ca.SX] | None = None,
    derivatives: DerivativeSettings | None = None,
) -> list[Kernel]:
    """``values``: a formulas leaf's run-time parameters as symbols (of ``parameters``);
    ``derivatives``: the spec's derivatives section (None: no derivative functions)."""
    n = leaf.nq
    sym = Symbols.make(n)
    graphs: ChainGraphs | FormulaGraphs
    if isinstance(leaf, KinematicTree):
        graphs, table, k = ChainGraphs(leaf, sym), _CHAIN, 0
    else:
        graphs, table = FormulaGraphs(leaf, sym, values), dict(_FORMULA)
        k = len(leaf.kinematics or ())
        if not k:
            del table["kinematics"], table["kinematics_jacobian"]
    loops = ChainLoops(graphs.tree, graphs.axes_and_inertias) if isinstance(graphs, ChainGraphs) else None
    kernels = [
        (
            loops
            and _looped(
                loops,
                name,
                doc,
                inputs,
                _resolve(shape, n, k),
                lambda name=name: getattr(graphs, name)(),
                sym,
                prefix,
                parameters,
            )
        )
        or _kernel(name, doc, inputs, _resolve(shape, n, k), getattr(graphs, name)(), sym, prefix, parameters)
        for name, (inputs, shape, doc) in table.items()
    ]
    if isinstance(graphs, ChainGraphs):
        kernels.append(_servo_terms(graphs, sym, n, prefix, loops))
    if derivatives is not None and derivatives.included(n):
        kernels += _derivative_kernels(graphs, derivatives.integrator, n, prefix, parameters)
    if isinstance(leaf, KinematicTree):
        return _singular_where_massless(leaf, kernels, prefix)
    return kernels


# the kernels that solve with M: a joint that moves no mass leaves them no finite result
SOLVE_WITH_M = frozenset(
    {
        "forward_dynamics",
        "forward_dynamics_derivatives",
        "mass_inverse",
        "discrete_dynamics",
        "discrete_dynamics_derivatives",
    }
)


def _singular_where_massless(tree: KinematicTree, kernels: list[Kernel], prefix: str) -> list[Kernel]:
    """The kernels of SOLVE_WITH_M told (Kernel.singular, and their doc) which joints move no
    mass, when some do: M is singular at every state (the URDF reader warns about them too)."""
    massless = [tree.joints[i].name for i in joints_without_inertia(tree)]
    if not massless:
        return kernels
    names = ", ".join(f"'{name}'" for name in massless)
    cause = (
        f"joint {names} moves" if len(massless) == 1 else f"joints {names} move"
    ) + " no mass or inertia (massless links after it), so M is singular at every state"
    return [
        replace(k, singular=cause, doc=f"{k.doc} Here {cause}.") if k.name[len(prefix) :] in SOLVE_WITH_M else k
        for k in kernels
    ]


def _derivative_kernels(graphs, integrator: str, n: int, prefix: str, parameters: ParameterSymbols) -> list[Kernel]:
    """The derivatives of the dynamics and the discrete model (robotgen.model.derivatives)."""
    d = DynamicsDerivatives(graphs)
    s = d.sym
    dt = ca.SX.sym("dt")
    state = [("q", s.q), ("qd", s.qd), ("tau", s.tau), ("dt", dt)]
    square = Matrix(n, n)
    id_schedule, fd_schedule = d.inverse_dynamics_derivatives_schedule(), d.forward_dynamics_derivatives_schedule()
    # a scheduled kernel's outputs are its schedule's, flattened on first use (make_kernel)
    dq, dqd = (None, None) if id_schedule else d.inverse_dynamics_derivatives()
    fq, fqd, minv = (None, None, None) if fd_schedule else d.forward_dynamics_derivatives()[1:]
    step = (
        "semi-implicit Euler (qd+ = qd + dt qdd, q+ = q + dt qd+)"
        if integrator == SEMI_IMPLICIT_EULER
        else "classical Runge-Kutta (RK4) on (qd, qdd)"
    )
    kernels = [
        make_kernel(
            prefix + "inverse_dynamics_derivatives",
            "Partial derivatives of inverse dynamics: d tau/dq and d tau/dqd (d tau/dqdd is M).",
            [("q", s.q), ("qd", s.qd), ("qdd", s.qdd)],
            [("dtau_dq", dq, square), ("dtau_dqd", dqd, square)],
            parameters,
            guarded=True,
            schedule=id_schedule,
        ),
        make_kernel(
            prefix + "forward_dynamics_derivatives",
            "Partial derivatives of forward dynamics: d qdd/dq, d qdd/dqd and d qdd/d tau = M^-1.",
            [("q", s.q), ("qd", s.qd), ("tau", s.tau)],
            [("dqdd_dq", fq, square), ("dqdd_dqd", fqd, square), ("dqdd_dtau", minv, square)],
            parameters,
            guarded=True,
            schedule=fd_schedule,
        ),
        make_kernel(
            prefix + "mass_inverse",
            "M(q)^-1 (L D L^T factorisation, then L^-T D^-1 L^-1, symmetric).",
            [("q", s.q)],
            [("mass_inverse", d.mass_inverse(), square)],
            parameters,
            guarded=True,
        ),
    ]
    q_next, qd_next = d.discrete_dynamics(integrator, dt)
    kernels.append(
        make_kernel(
            prefix + "discrete_dynamics",
            f"One step of length dt, tau held: {step}. Returns q+, qd+.",
            state,
            [("q_next", q_next, (n, 1)), ("qd_next", qd_next, (n, 1))],
            parameters,
            guarded=True,
        )
    )
    step_schedule = d.discrete_dynamics_derivatives_schedule(integrator, dt)
    shapes = [(n, 1), (n, 1), Matrix(2 * n, 2 * n), Matrix(2 * n, n)]
    step_outputs: Sequence[ca.SX | None] = (
        (None, None, None, None) if step_schedule is not None else d.discrete_dynamics_derivatives(integrator, dt)
    )
    kernels.append(
        make_kernel(
            prefix + "discrete_dynamics_derivatives",
            f"One step ({step}) and its Jacobians: q+, qd+, A = d(q+, qd+)/d(q, qd), B = d(q+, qd+)/d tau.",
            state,
            [(name, x, shape) for name, x, shape in zip(("q_next", "qd_next", "A", "B"), step_outputs, shapes)],
            parameters,
            guarded=True,
            schedule=step_schedule,
        )
    )
    if isinstance(graphs, ChainGraphs):
        kernels.append(
            make_kernel(
                prefix + "jacobian_derivative",
                "dJ/dt (6 x n): the time derivative of the tip Jacobian; jacobian_derivative qd = jacobian_dot_qd.",
                [("q", s.q), ("qd", s.qd)],
                [("jacobian_derivative", graphs.jacobian_derivative(), Matrix(6, n))],
                parameters,
                guarded=True,
            )
        )
    return kernels


def _servo_terms(graphs: ChainGraphs, sym: Symbols, n: int, prefix: str, loops: ChainLoops | None) -> Kernel:
    """What one computed-torque cycle needs, in one call sharing sin/cos and kinematics."""
    outputs = [
        ("mass", graphs.mass, Matrix(n, n)),
        ("nonlinear", graphs.nonlinear, (n, 1)),
        ("jacobian", graphs.jacobian, Matrix(6, n)),
        ("jacobian_dot_qd", graphs.jacobian_dot_qd, (6, 1)),
    ]
    schedule = None
    if loops is not None and _long([sym.q, sym.qd], lambda: [o[1]() for o in outputs], n):
        schedule = ScheduleBuilder([sym.q, sym.qd], [n * n, n, 6 * n, 6])
        loops.servo_terms(schedule, sym.qd, graphs.jacobian(), graphs.jacobian_dot_qd())
        built: list[tuple[str, ca.SX | None, Shape]] = [(name, None, shape) for name, _, shape in outputs]
    else:
        built = [(name, build(), shape) for name, build, shape in outputs]
    return make_kernel(
        prefix + "servo_terms",
        "M(q), C(q, qd) qd + N, the tip Jacobian J and Jdot qd in one "
        "call: a computed-torque servo cycle's terms, sharing sin/cos and kinematics.",
        [("q", sym.q), ("qd", sym.qd)],
        built,
        schedule=schedule,
    )
