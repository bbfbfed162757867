"""The controllers' periods of a spec (robotgen.model.rate_groups): each checked where the spec
sets it, against the fastest period, the controllers above it and the slowest period."""

from __future__ import annotations

import math

from robotgen.frontend.collector import Collector
from robotgen.frontend.document import Path
from robotgen.model.laws.registry import LAWS, tree_laws
from robotgen.model.rate_groups import DEFAULT_PERIOD, MAX_TICKS, PERIOD_TOLERANCE, ticks_of
from robotgen.model.simulation import SimulationSettings
from robotgen.model.system import ControlNode, Node


class RateReader(Collector):
    """The `period` of CONTROL nodes."""

    def check_periods(self, nodes: dict[str, Node], root: str, simulation: SimulationSettings | None) -> None:
        """Every controller's period (its own, its nearest controller ancestor's, the topmost
        ones simulation.dt's or DEFAULT_PERIOD) is an integer multiple of the fastest (at most
        MAX_TICKS of them), a multiple of every controller's below it, and a divisor of the
        slowest; a period under a root law is refused. Reported at the spec's `period`."""
        controls = {name: n for name, n in nodes.items() if isinstance(n, ControlNode)}
        if any(n.period is not None and not (math.isfinite(n.period) and n.period > 0) for n in controls.values()):
            return  # a period that is no positive number is reported where it was read
        root_node = nodes.get(root)
        if isinstance(root_node, ControlNode) and LAWS[root_node.law].is_root:
            for name, n in controls.items():
                if n.period is not None and name != root:  # the root law's own is refused by its reader
                    self.at_key(
                        self._path(name),
                        f"the root '{root}' is law {root_node.law}, which makes the "
                        "module's functions itself; a period applies to a tree of "
                        f"tree laws ({', '.join(tree_laws())}) compiled into servo steps",
                    )
            return
        dt_given = simulation is not None and "dt" in simulation.locations
        default = simulation.dt if simulation is not None else DEFAULT_PERIOD
        if not (math.isfinite(default) and default > 0):
            return  # simulation.dt given as an expression that is no period: simulate refuses it
        periods: dict[str, float] = {}
        parent: dict[str, str | None] = {}

        def visit(name: str, above: str | None, seen: set[str]) -> None:
            node = nodes.get(name)
            if node is None or name in seen:
                return  # a dangling reference or a cycle: reported by the tree check
            seen = seen | {name}
            if isinstance(node, ControlNode) and not LAWS[node.law].is_root:
                own = node.period
                periods[name] = own if own is not None else periods[above] if above else default
                parent[name] = above
                above = name
            for child in node.children:
                visit(child, above, seen)

        if root_node is None:
            return
        visit(root, None, set())
        if not periods:
            return
        fastest = min(periods, key=periods.__getitem__)
        slowest = max(periods, key=periods.__getitem__)
        f, s = periods[fastest], periods[slowest]

        def owner(name: str | None) -> str | None:
            """The controller whose own period ``name`` runs at (None: simulation.dt's or the default)."""
            while name is not None and controls[name].period is None:
                name = parent[name]
            return name

        def source(name: str) -> str:
            """Where a controller's period comes from, for messages."""
            own = owner(name)
            if own == name:
                return f"'{name}'"
            return f"'{name}', from " + (f"'{own}'" if own else "simulation.dt" if dt_given else "the default")

        wrong: set[str] = set()  # periods reported: not checked again through the ones that take them
        for name, p in periods.items():  # the walk from the root: a controller after the ones above it
            if controls[name].period is None:
                continue  # inherited: its owner's period is checked where it is set
            path = self._path(name)
            wrong.add(name)
            ratio = p / f
            if not ratio < MAX_TICKS + 0.5:
                self.at_value(
                    path,
                    f"{p:g} s is {ratio:.4g} times the fastest period in the tree ({f:g} s of "
                    f"{source(fastest)}); a group may span at most {MAX_TICKS} fastest periods",
                )
            elif ticks_of(p, f) is None:
                self.at_value(
                    path,
                    f"{p:g} s is not an integer multiple of the fastest period in the tree ({f:g} s "
                    f"of {source(fastest)}): the groups run on ticks of the fastest",
                )
            elif (above := parent[name]) is not None and owner(above) not in wrong and not divides(p, periods[above]):
                slower = "longer than" if periods[above] < p else "not a divisor of"
                self.at_value(
                    path,
                    f"{p:g} s is {slower} the period of '{above}' above it ({periods[above]:g} s of "
                    f"{source(above)}): a controller runs at the rate of the one above it or an "
                    "integer multiple of it, whose writes it holds between their ticks",
                )
            else:
                wrong.discard(name)
        for name, p in periods.items():
            if (
                controls[name].period is not None
                and name not in wrong
                and owner(slowest) not in wrong
                and not divides(p, s)
            ):
                self.at_value(
                    self._path(name),
                    f"{p:g} s does not divide the slowest period in the tree ({s:g} s of "
                    f"{source(slowest)}): the groups' ticks must line up once per slowest "
                    "period",
                )
        tops = [name for name in periods if parent[name] is None]
        if (
            dt_given
            and simulation is not None
            and all(controls[name].period is not None for name in tops)
            and ticks_of(simulation.dt, f) != 1
        ):
            self.at_value(
                ("simulation", "dt"),
                f"{simulation.dt:g} s is not the fastest controller period "
                f"({f:g} s of '{fastest}'): every topmost controller sets its "
                "period, and the plant steps at the fastest; drop dt or make it "
                f"{f:g}",
            )

    @staticmethod
    def _path(name: str) -> Path:
        return ("nodes", name, "control", "period")


def divides(small: float, large: float) -> bool:
    """large / small is a whole number (to PERIOD_TOLERANCE)."""
    ratio = large / small
    if not math.isfinite(ratio):
        return False
    n = round(ratio)
    return n >= 1 and abs(ratio - n) <= PERIOD_TOLERANCE * n
