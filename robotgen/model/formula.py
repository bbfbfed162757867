"""DEFINE by formulas (Deno et al. 1990, eq 3.1 and StyxDefinitions.m): named coordinates
and M, C, N written as expressions. The expressions are parsed and checked by
robotgen.model.expression; they become CasADi graphs in robotgen.symbolic.formulas."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robotgen.errors import Location
from robotgen.model.chain import KinematicTree
from robotgen.model.expression import Expr


@dataclass(frozen=True, eq=False)
class Mechanism:
    """The rigid bodies behind a formulas leaf, for an independent simulator (MuJoCo,
    robotgen.simulation.mujoco): a chain whose joint positions q give the leaf's coordinates
    affinely, theta = T q + offset (absolute link angles from relative joints, say), and
    whose tip frame is the point the leaf's ``kinematics`` (or, without them, its
    coordinates) put the fingertip at. The formulas stay the model robotgen compiles; the
    simulator checks that the mechanism reproduces them."""

    tree: KinematicTree
    coordinates: tuple[Expr, ...]  # the leaf's coordinates in the chain's joint names
    T: np.ndarray  # (nq, nq) d theta / d q, invertible
    offset: np.ndarray  # (nq,) theta at q = 0
    location: Location  # where the spec gives it (for the simulator's messages)


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
    mechanism: Mechanism | None = None  # the bodies an independent simulator builds it from

    @property
    def nq(self) -> int:
        """The number of coordinates."""
        return len(self.coordinates)
