"""Resolved motion rate control (Whitney 1972), a root law: of a chain (chain.py: command
frames, axis masks, damped and redundant resolution, position control by axis/angle, the
eq-19 regulator) or of a composite robot in its own coordinates (composite.py)."""

from __future__ import annotations

from robotgen.model.laws import RESOLVED_RATE
from robotgen.model.system import RobotSystem
from robotgen.symbolic.kernel import Kernel
from robotgen.symbolic.root_laws.law import RootLaw
from robotgen.symbolic.root_laws.resolved_rate.chain import chain_kernels, chain_report
from robotgen.symbolic.root_laws.resolved_rate.composite import composite_kernels, composite_report


def kernels(system: RobotSystem) -> list[Kernel]:
    """The resolved motion rate control kernels (Whitney 1972) of a chain or a composite root."""
    return composite_kernels(system) if system.rate_controls_composite else chain_kernels(system)


def report(system: RobotSystem) -> tuple[dict, dict]:
    """(info entries, module attributes) of a resolved-rate spec."""
    return composite_report(system) if system.rate_controls_composite else chain_report(system)


LAW = RootLaw(RESOLVED_RATE, kernels, report)
