"""Every control law, one line each (robotgen.model.laws.descriptor.Law): the one table the
spec schema, the spec front end, the symbolic layer and ``robotgen simulate`` read.

Adding a law is its module(s) and one line here (docs/ARCHITECTURE.md, "Adding a law")."""

from __future__ import annotations

from robotgen.model.laws import (
    COMPUTED_TORQUE,
    FEEDFORWARD,
    HYBRID,
    IMPEDANCE,
    PD,
    PD_FEEDFORWARD,
    RESOLVED_ACCELERATION,
    RESOLVED_ADAPTIVE,
    RESOLVED_RATE,
)
from robotgen.model.laws.descriptor import Law

_TREE = "robotgen.symbolic.control"
_ROOT = "robotgen.symbolic.root_laws"
_FORCE = "robotgen.frontend.control.force"
_HAND = "robotgen.frontend.control.hand"
_RATE = "robotgen.frontend.control.resolved_rate"
_CONTROLLER = "it makes the module's controller"

LAWS: dict[str, Law] = {
    law.name: law
    for law in (
        Law(COMPUTED_TORQUE, f"{_TREE}.computed_torque:LAW", stateful=True, expected=True),
        Law(
            FEEDFORWARD,
            f"{_TREE}.feedforward:LAW",
            stateful=True,
            expected=True,
            gains=False,
            no_gains="it is computed torque with Kp = Kv = 0",
        ),
        Law(PD_FEEDFORWARD, f"{_TREE}.pd_feedforward:LAW"),
        Law(PD, f"{_TREE}.pd:LAW", internal_forces=False),
        Law(
            IMPEDANCE,
            f"{_TREE}.impedance:LAW",
            gains=False,
            no_gains="its stiffness and damping go under impedance",
            reads_forces=True,
            settings=f"{_FORCE}:ForceLawReader.check_impedance",
            schema=f"{_FORCE}:IMPEDANCE_SCHEMA",
        ),
        Law(
            HYBRID,
            f"{_TREE}.hybrid:LAW",
            reads_forces=True,
            stateful=True,
            settings=f"{_FORCE}:ForceLawReader.check_hybrid",
            schema=f"{_FORCE}:HYBRID_SCHEMA",
        ),
        Law(
            RESOLVED_RATE,
            f"{_ROOT}.resolved_rate:LAW",
            root="it outputs joint rates, which no node above can use",
            gains=False,
            settings=f"{_RATE}:ResolvedRateReader.check_rate_control",
            schema=f"{_RATE}:SCHEMA",
            simulation="robotgen.simulation.regulator",
        ),
        Law(
            RESOLVED_ACCELERATION,
            f"{_ROOT}.resolved_acceleration:LAW",
            root=_CONTROLLER,
            hand_frame=True,
            gains=False,
            settings=f"{_HAND}:HandLawReader.check_acceleration_control",
            schema=f"{_HAND}:RESOLVED_ACCELERATION_SCHEMA",
            simulation="robotgen.simulation.hand",
        ),
        Law(
            RESOLVED_ADAPTIVE,
            f"{_ROOT}.resolved_adaptive:LAW",
            root=_CONTROLLER,
            hand_frame=True,
            gains=False,
            stateful=True,
            settings=f"{_HAND}:HandLawReader.check_adaptive_control",
            schema=f"{_HAND}:RESOLVED_ADAPTIVE_SCHEMA",
            simulation="robotgen.simulation.hand",
        ),
    )
}


def tree_laws() -> tuple[str, ...]:
    """The names of the laws that compose in a robot tree, in table order."""
    return tuple(name for name, law in LAWS.items() if not law.is_root)


def root_laws() -> tuple[str, ...]:
    """The names of the laws that are the root of their spec, in table order."""
    return tuple(name for name, law in LAWS.items() if law.is_root)
