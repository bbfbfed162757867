"""DEFINE by formulas (Deno et al. 1990, eq 3.1 and StyxDefinitions.m): named coordinates
and M, C, N written as expressions. The expressions are parsed and checked by
robotgen.model.expression; they become CasADi graphs in robotgen.symbolic.formulas."""
from __future__ import annotations

from dataclasses import dataclass, field

from robotgen.model.expression import Expr


@dataclass(frozen=True, eq=False)
class FormulaRobot:
    """A leaf robot given by its dynamic attributes.

    mass:       nq x nq expressions in the coordinates and parameters.
    coriolis:   nq x nq expressions in coordinates, velocities, parameters; None means
                "derive from M by Christoffel symbols".
    nonlinear:  nq expressions N(q, qd) (gravity, friction); None means zero.
    kinematics: optional output map x = f(q) (the finger-tip position, for ATTACH).
    outputs:    names of the kinematics outputs (used by ATTACH formulas and inverse_kinematics).
    inverse_kinematics: optional q = f^-1(x), expressions in the outputs and parameters
                (StyxDefinitions.m's RobotInverse); lets positions flow down through ATTACH.
    units:      optional unit ("m" or "rad") of coordinates and outputs, by name: labels
                plots and reports (forces in N on "m" coordinates, torques in N m on "rad").
    """

    name: str
    coordinates: tuple[str, ...]
    velocities: tuple[str, ...]
    parameters: dict[str, float]
    mass: tuple[tuple[Expr, ...], ...]
    coriolis: tuple[tuple[Expr, ...], ...] | None
    nonlinear: tuple[Expr, ...] | None
    kinematics: tuple[Expr, ...] | None
    outputs: tuple[str, ...] = ()
    inverse_kinematics: tuple[Expr, ...] | None = None
    units: dict[str, str] = field(default_factory=dict)
    runtime: frozenset[str] = frozenset()  # parameters read at run time (robotgen.model.parameters)

    @property
    def nq(self) -> int:
        return len(self.coordinates)
