"""`robotgen simulate` for a multi-rate tree: its MultiRateController (each rate group at its
own period, the plant stepped at the fastest) beside the single-rate servo_step of the same tree
(every controller at the fastest period), on one plant; the report gives each run's tracking
error and its cost in arithmetic operations per second of control (each group's operations
per step times its rate, summed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robotgen.simulation import tree as simulate
from robotgen.simulation.model_plant import ModulePlant
from robotgen.simulation.tree import Result

SINGLE_RATE = "single_rate"  # the file stem's suffix of the single-rate run


@dataclass(frozen=True)
class GroupCost:
    """One rate group's step: its controllers, period [s] and operations per step."""

    step: str
    controllers: tuple[str, ...]
    period: float
    operations: int  # of one step

    @property
    def per_second(self) -> float:
        """Operations per second: one step's over the period."""
        return self.operations / self.period


@dataclass(frozen=True)
class Cost:
    """Operations per second of control of both runs."""

    groups: tuple[GroupCost, ...]  # the multi-rate run's, fastest first
    single: GroupCost  # servo_step at the fastest period

    @property
    def multi_rate(self) -> float:
        """Operations per second of the MultiRateController: every group's summed."""
        return sum(g.per_second for g in self.groups)


def cost(info: dict) -> Cost:
    """The cost of a multi-rate module's two runs, from its info()["multirate"]."""
    m = info["multirate"]
    groups = tuple(GroupCost(g["step"], tuple(g["controllers"]), g["period"], g["operations"]) for g in m["groups"])
    every = tuple(c for g in groups for c in g.controllers)
    return Cost(groups, GroupCost(m["single_rate"], every, groups[0].period, m["single_rate_operations"]))


def run(module, settings, rest, plant=ModulePlant) -> tuple[Result, Result]:
    """(the multi-rate run, the single-rate run), both stepping the plant every settings.dt
    (the fastest period)."""
    return (simulate.run(module, settings, rest, plant, multirate=True), simulate.run(module, settings, rest, plant))


def _rms(e: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(e**2, axis=0))


def compare(multi: Result, single: Result, info: dict) -> str:
    """Both runs side by side: per root coordinate the largest and RMS tracking error, then the
    cost of each."""
    c = cost(info)
    base = c.groups[0].period
    lines = [
        f"simulated {multi.t[-1]:.3f} s in {len(multi.t) - 1} steps of {base:g} s on the {multi.plant} plant"
        + (f" ({multi.plant_note})" if multi.plant_note else ""),
        "rate groups:",
    ]
    for g in c.groups:
        lines.append(f"  {g.step}: {', '.join(g.controllers)} at {1 / g.period:g} Hz")
    head = f"single rate (every controller at {1 / base:g} Hz)"
    late = multi.t >= multi.t[-1] / 2
    lines += [
        "tracking error x - x_d (RMS over the run, and largest over its second half), side by side:",
        f"  {'':>12}  {'multi-rate':<33}  {'':>12}{head}",
    ]
    for i, name in enumerate(multi.names):
        unit = multi.units[i] if i < len(multi.units) else ""
        em, es = multi.error[:, i], single.error[:, i]
        lines.append(
            f"  {name:>12}  rms {_rms(em):.3e}, late max {np.abs(em[late]).max():.3e}  {'':>12}"
            f"rms {_rms(es):.3e}, late max {np.abs(es[late]).max():.3e}{f' [{unit}]' if unit else ''}"
        )
    lines.append("operations per second of control (each step's arithmetic operations times its rate):")
    for g in c.groups:
        lines.append(f"  multi-rate   {g.step}: {g.operations:6d} x {1 / g.period:8g} Hz = {g.per_second:12.0f}")
    lines.append(f"  multi-rate   total: {c.multi_rate:31.0f}")
    lines.append(
        f"  single rate  {c.single.step}: {c.single.operations:6d} x {1 / base:8g} Hz = {c.single.per_second:12.0f}"
    )
    lines.append(f"the multi-rate tree costs {c.multi_rate / c.single.per_second:.3f} of the single-rate one")
    for label, result in (("the multi-rate run", multi), ("the single-rate run", single)):
        contacts = simulate.force_lines(result) + simulate.contact_lines(result)
        lines += [f"{label}:", *(f"  {line}" for line in contacts)] if contacts else []
    return "\n".join(lines)
