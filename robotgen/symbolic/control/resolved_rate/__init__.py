"""Resolved motion rate control (Whitney 1972), a root law: of a chain (chain.py: command
frames, axis masks, damped and redundant resolution, position control by axis/angle, the
eq-19 regulator) or of a composite robot in its own coordinates (composite.py)."""
from __future__ import annotations

from robotgen.model.laws import RESOLVED_RATE
from robotgen.model.system import RobotSystem
from robotgen.symbolic.control.law import RootLaw
from robotgen.symbolic.control.resolved_rate.chain import rate_control_kernels, rate_control_report
from robotgen.symbolic.control.resolved_rate.composite import tree_rate_kernels, tree_rate_report
from robotgen.symbolic.kernel import Kernel


def kernels(system: RobotSystem) -> list[Kernel]:
    return tree_rate_kernels(system) if system.rate_controls_composite else rate_control_kernels(system)


def report(system: RobotSystem) -> tuple[dict, dict]:
    return tree_rate_report(system) if system.rate_controls_composite else rate_control_report(system)


LAW = RootLaw(RESOLVED_RATE, kernels, report)
