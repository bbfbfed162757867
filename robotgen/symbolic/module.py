"""What a system's module holds, by its root: one leaf robot's functions
(robotgen.symbolic.leaf_kernels), a root law's (robotgen.symbolic.root_laws), or a
robot tree's (robotgen.symbolic.system_kernels)."""

from __future__ import annotations

from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.laws.registry import LAWS
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.rate_groups import multi_rate_groups
from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel, ParameterSymbols
from robotgen.symbolic.leaf_kernels import leaf_kernels
from robotgen.symbolic.rate_steps import MultiRate, multi_rate
from robotgen.symbolic.root_laws.law import Controller, RootLaw
from robotgen.symbolic.system import leaf_values
from robotgen.symbolic.system_kernels import system_kernels


def kernels_for(system: RobotSystem) -> list[Kernel]:
    """Every function the module of ``system`` emits, as CasADi Functions with ports."""
    if system.is_single_leaf:
        parameters = ParameterSymbols.of(runtime_parameters(system))
        root = system.define(system.root)
        if not isinstance(root.leaf, (KinematicTree, FormulaRobot)):  # the front end refuses a lone payload
            raise TypeError(f"a module of one leaf needs a robot; '{system.root}' is a {type(root.leaf).__name__}")
        return leaf_kernels(
            root.leaf, parameters=parameters, values=leaf_values(parameters, root), derivatives=system.derivatives
        )
    if system.root_law is not None:
        return _root_law(system).kernels(system)
    return system_kernels(system)


def module_extras(system: RobotSystem) -> tuple[dict, dict]:
    """(extra info() and manifest keys, module attributes) worked out in the symbolic layer:
    a root law's settings and reports (a resolved-rate controller's regulator gains)."""
    if system.root_law is not None:
        return _root_law(system).report(system)
    return {}, {}


def controllers_for(system: RobotSystem) -> list[Controller | MultiRate]:
    """The controller classes the module offers (a hand law's, each around one of the
    kernels; a multi-rate tree's MultiRateController, around its rate groups' steps)."""
    law = _root_law(system) if system.root_law else None
    if law is not None and law.controller is not None:
        return [law.controller(system)]
    groups = multi_rate_groups(system)
    return [multi_rate(system, groups)] if groups is not None else []


def _root_law(system: RobotSystem) -> RootLaw:
    """The symbolic part of the root's law (robotgen.model.laws.registry)."""
    if system.root_law is None:
        raise TypeError(f"the root '{system.root}' has no root law")
    return LAWS[system.root_law].part("kernels")
