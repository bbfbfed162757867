"""A formula-defined leaf robot (Deno et al. 1990, eq 3.1) as CasADi SX expressions."""

from __future__ import annotations

import casadi as ca

from robotgen.model.expression import MATH_LIB, evaluate
from robotgen.model.formula import FormulaRobot
from robotgen.symbolic.rigid_body.chain import Symbols
from robotgen.symbolic.rigid_body.cholesky import cholesky_solve
from robotgen.symbolic.rigid_body.christoffel import coriolis_matrix


def _folding(name: str, graph):
    """``graph`` on symbolic arguments; on numbers only (a formula's constant part, a folded
    parameter), the correctly rounded value of MATH_LIB (robotgen.numeric.exact): the value
    the spec's checks saw (M's positive definiteness), the same on every machine. CasADi
    would fold it with this machine's libm."""
    fold = MATH_LIB[name]

    def apply(*args):
        return fold(*args) if all(isinstance(a, float) for a in args) else graph(*args)

    return apply


CASADI_LIB = {
    name: _folding(name, graph)
    for name, graph in {
        "sin": ca.sin,
        "cos": ca.cos,
        "tan": ca.tan,
        "asin": ca.asin,
        "acos": ca.acos,
        "atan": ca.atan,
        "atan2": ca.atan2,
        "exp": ca.exp,
        "log": ca.log,
        "sqrt": ca.sqrt,
        "abs": ca.fabs,
        "tanh": ca.tanh,
        "sinh": ca.sinh,
        "cosh": ca.cosh,
        "sign": ca.sign,
        "min": ca.fmin,
        "max": ca.fmax,
        "pow": lambda a, b: a**b,
    }.items()
}


def expression_column(exprs, env) -> ca.SX:
    """The expressions as a CasADi column, names bound by ``env``."""
    return ca.vertcat(*[ca.SX(evaluate(e, env, CASADI_LIB)) for e in exprs])


def expression_matrix(rows, env) -> ca.SX:
    """A matrix of formula expressions as SX, rows evaluated in ``env``."""
    return ca.vertcat(*[expression_column(row, env).T for row in rows])


def expression_map(exprs, names, parameters):
    """x -> the expressions with ``names`` bound to the entries of x (an inverse map given
    as formulas: StyxDefinitions.m's RobotInverse, an attach's h^-1)."""

    def apply(x: ca.SX) -> ca.SX:
        env = dict(parameters)
        env.update({name: x[i] for i, name in enumerate(names)})
        return expression_column(exprs, env)

    return apply


class FormulaGraphs:
    """A formulas leaf's graphs: M, C, N and kinematics from its expressions in the shared symbols q, qd, qdd, tau."""

    def __init__(self, robot: FormulaRobot, sym: Symbols, values: dict[str, ca.SX] | None = None):
        """``values``: run-time parameters as symbols, by name (the others are numbers)."""
        self.robot = robot
        self.sym = sym
        env: dict[str, object] = {**robot.parameters, **(values or {})}
        env.update({name: sym.q[i] for i, name in enumerate(robot.coordinates)})
        env.update({name: sym.qd[i] for i, name in enumerate(robot.velocities)})
        self._env = env

    def _matrix(self, rows) -> ca.SX:
        return expression_matrix(rows, self._env)

    def mass(self) -> ca.SX:
        """M(q) (n, n)."""
        return self._matrix(self.robot.mass)

    def coriolis(self) -> ca.SX:
        """C(q, qd) (n, n): the formula's, else the Christoffel symbols of M."""
        if self.robot.coriolis is None:
            return coriolis_matrix(self.mass(), self.sym.q, self.sym.qd)
        return self._matrix(self.robot.coriolis)

    def n_term(self, qd: ca.SX) -> ca.SX:
        """N at velocity ``qd`` (n,), zero when the leaf has none."""
        if self.robot.nonlinear is None:
            return ca.SX.zeros(self.robot.nq, 1)
        N = expression_column(self.robot.nonlinear, self._env)
        return ca.substitute(N, self.sym.qd, qd)

    def gravity(self) -> ca.SX:
        """Gravity: N at qd = 0 (n,)."""
        return self.n_term(ca.SX.zeros(self.robot.nq, 1))

    def nonlinear(self) -> ca.SX:
        """C(q, qd) qd + N(q, qd) (n,)."""
        return self.coriolis() @ self.sym.qd + self.n_term(self.sym.qd)

    def inverse_dynamics(self) -> ca.SX:
        """tau = M qdd + C qd + N (n,)."""
        return self.mass() @ self.sym.qdd + self.nonlinear()

    def forward_dynamics(self) -> ca.SX:
        """qdd = M^-1 (tau - C qd - N) (n,), by L D L^T."""
        return cholesky_solve(self.mass(), self.sym.tau - self.nonlinear())

    def kinematics(self) -> ca.SX:
        """The output x(q), as the leaf's kinematics formulas give it."""
        return expression_column(self.robot.kinematics, self._env)

    def kinematics_jacobian(self) -> ca.SX:
        """dx/dq of the output: (outputs, n)."""
        return ca.jacobian(self.kinematics(), self.sym.q)
