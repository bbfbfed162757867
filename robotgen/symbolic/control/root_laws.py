"""The root control laws by name (robotgen.model.laws.ROOT_LAWS): laws that are the root of
their spec and make the module's functions themselves (robotgen.symbolic.control.law.RootLaw)."""
from __future__ import annotations

from robotgen.symbolic.control import resolved_acceleration, resolved_adaptive, resolved_rate
from robotgen.symbolic.control.law import RootLaw

ROOT_LAWS: dict[str, RootLaw] = {m.LAW.name: m.LAW for m in (resolved_rate, resolved_acceleration, resolved_adaptive)}
