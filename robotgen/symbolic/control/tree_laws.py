"""The tree control laws by name (robotgen.model.laws.TREE_LAWS): one module each."""
from __future__ import annotations

from robotgen.symbolic.control import computed_torque, feedforward, hybrid, impedance, pd, pd_feedforward
from robotgen.symbolic.control.law import TreeLaw

TREE_LAWS: dict[str, TreeLaw] = {m.LAW.name: m.LAW for m in (computed_torque, feedforward, pd_feedforward, pd,
                                                              impedance, hybrid)}
