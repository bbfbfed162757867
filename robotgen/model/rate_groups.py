"""Rate groups of a robot tree: its CONTROL nodes by the period each runs at.

The 1990 paper motivates its hierarchy by time scales: fast low-level loops (spinal reflexes,
finger stiffness) under slower upper levels (ch 1, §4.3), and asks whether "lower computation
rates may be practical for higher level robots/controllers" (ch 6). A CONTROL node may set
its own ``period``; one without takes its nearest controller ancestor's, the topmost ones the
tree's ``simulation.dt`` (or DEFAULT_PERIOD). Controllers of one period form a group, g0 the
fastest. Every period is an integer multiple of the fastest (its ``ticks``), each controller
runs at least as fast as the one above it, and every period divides the slowest, so the
whole schedule repeats once per slowest period (the frame).

What a controller writes down (wr, eq 5.1: x_e, xd_e, xdd_e, F_e, F_i) crosses to a faster
group at a boundary: a controller of a faster group directly below it (ATTACH nodes between
them). There the writer's trajectory is held (zero-order hold) in the buffer the paper gives a
controlled robot's wr (§3.4, Fig 3.3), and the faster group reads it at each of its ticks
until the writer's next tick. Measurements go the other way without a buffer: every group
reads the leaves' sensed state at its own ticks. Nodes above every controller (a root ATTACH)
are evaluated by each group that has a controller below them, from the root trajectory the
caller writes each tick; a leaf no controller drives takes its torque from the fastest group."""

from __future__ import annotations

from dataclasses import dataclass, field

from robotgen.model.laws.registry import LAWS
from robotgen.model.signature import robot_leaves
from robotgen.model.simulation import SimulationSettings
from robotgen.model.system import AttachNode, ControlNode, DefineNode, RobotSystem

# the period of a tree whose controllers set none and whose spec has no simulation.dt [s]
DEFAULT_PERIOD = SimulationSettings().dt
# how many fastest periods a slower group's period may span (and the frame: the slowest's)
MAX_TICKS = 10_000
# two periods are one when they differ by this much relative to the larger (decimal inputs)
PERIOD_TOLERANCE = 1e-9


@dataclass(frozen=True)
class RateGroup:
    """One rate group: its controllers (walk order), its period and what its step reads and
    writes besides the sensed state."""

    index: int
    period: float  # seconds
    ticks: int  # fastest periods per period: the group runs at ticks 0, ticks, 2 ticks, ...
    controllers: tuple[str, ...]
    reads_root: bool = False  # evaluates nodes from the root down: takes the root trajectory
    reads: tuple[str, ...] = ()  # boundary controllers it runs from their held wr
    writes: tuple[str, ...] = ()  # boundary controllers whose wr it writes (held for a faster group)
    drives: tuple[str, ...] = ()  # the leaves whose torques it computes

    @property
    def rate(self) -> float:
        """Its rate [Hz]."""
        return 1.0 / self.period


@dataclass(frozen=True)
class RateGroups:
    """A tree's controllers grouped by period (fastest first), and the group of each CONTROL node."""

    groups: tuple[RateGroup, ...]  # fastest first
    group_of: dict[str, int] = field(default_factory=dict)  # CONTROL node -> its group

    @property
    def multi_rate(self) -> bool:
        """Whether the tree has more than one period."""
        return len(self.groups) > 1

    @property
    def frame_ticks(self) -> int:
        """Fastest periods in one period of the slowest group: the schedule's repeat."""
        return self.groups[-1].ticks

    @property
    def base_period(self) -> float:
        """The fastest period [s], the tick of every group."""
        return self.groups[0].period

    @property
    def boundaries(self) -> tuple[str, ...]:
        """Every held wr, in the order the slower groups write them (slowest first)."""
        return tuple(name for g in reversed(self.groups) for name in g.writes)

    def due(self, tick: int) -> tuple[int, ...]:
        """The groups that run at ``tick`` (a count of fastest periods), slowest first: a
        slower group's writes are held for the faster ones from that same tick on."""
        return tuple(g.index for g in reversed(self.groups) if tick % g.ticks == 0)


def tree_controllers(system: RobotSystem) -> list[ControlNode]:
    """The tree-law controllers, in walk order (a root law's tree has none that run here)."""
    if system.root_law is not None or system.is_single_leaf:
        return []
    return [n for n in system.walk() if isinstance(n, ControlNode) and not LAWS[n.law].is_root]


def controller_periods(system: RobotSystem, default: float | None = None) -> dict[str, float]:
    """Each tree-law controller's period: its own, else its nearest controller ancestor's,
    else ``default`` (simulation.dt, or DEFAULT_PERIOD, when not given) for the topmost ones."""
    if not tree_controllers(system):
        return {}
    if default is None:
        default = system.simulation.dt if system.simulation is not None else DEFAULT_PERIOD
    out: dict[str, float] = {}

    def visit(name: str, above: float) -> None:
        node = system.nodes[name]
        if isinstance(node, ControlNode):
            above = node.period if node.period is not None else above
            out[name] = above
        for child in node.children:
            visit(child, above)

    visit(system.root, default)
    return out


def ticks_of(period: float, fastest: float) -> int | None:
    """period / fastest when it is a whole number (to PERIOD_TOLERANCE) no larger than
    MAX_TICKS; None otherwise."""
    ratio = period / fastest
    if not ratio < MAX_TICKS + 0.5:  # also inf and NaN
        return None
    n = round(ratio)
    return n if n >= 1 and abs(ratio - n) <= PERIOD_TOLERANCE * n else None


def rate_groups(system: RobotSystem) -> RateGroups | None:
    """The groups of a tree of tree laws by its controllers' periods (the spec front end has
    checked them); None for a leaf or a root law's spec."""
    periods = controller_periods(system)
    if not periods:
        return None
    fastest = min(periods.values())
    ticks: dict[str, int] = {}
    for name, p in periods.items():
        t = ticks_of(p, fastest)
        if t is None:  # robotgen.frontend.rates refuses such a spec
            raise ValueError(f"controller '{name}': period {p:g} s is not a whole multiple of {fastest:g} s")
        ticks[name] = t
    distinct = sorted(set(ticks.values()))
    group_of = {name: distinct.index(t) for name, t in ticks.items()}
    by_group = [next(periods[n] for n in periods if group_of[n] == k) for k in range(len(distinct))]
    return partition(system, group_of, tuple(by_group))


def partition(system: RobotSystem, group_of: dict[str, int], periods: tuple[float, ...]) -> RateGroups:
    """The groups of a given assignment of controllers to groups (group k runs every
    periods[k]; periods ascending, each a multiple of the first): what each group reads,
    writes and drives. A boundary is a controller of another group below a controller."""
    n = len(periods)
    reads_root = [False] * n
    reads: list[list[str]] = [[] for _ in range(n)]
    writes: list[list[str]] = [[] for _ in range(n)]
    drives: list[list[str]] = [[] for _ in range(n)]
    actuated = set(robot_leaves(system))

    def visit(name: str, writer: int | None) -> None:
        node = system.nodes[name]
        if isinstance(node, ControlNode):
            g = group_of[name]
            if writer is None:
                reads_root[g] = True
            elif writer != g:
                writes[writer].append(name)
                reads[g].append(name)
            visit(node.robot, g)
        elif isinstance(node, AttachNode):
            for robot in node.robots:
                visit(robot, writer)
        elif isinstance(node, DefineNode) and name in actuated:
            g = 0 if writer is None else writer
            reads_root[g] = reads_root[g] or writer is None
            drives[g].append(name)

    visit(system.root, None)
    controllers = [[c for c, g in group_of.items() if g == k] for k in range(n)]
    order = {node.name: i for i, node in enumerate(system.walk())}
    groups = tuple(
        RateGroup(
            k,
            periods[k],
            max(1, round(periods[k] / periods[0])),
            tuple(sorted(controllers[k], key=order.__getitem__)),
            reads_root[k],
            tuple(sorted(reads[k], key=order.__getitem__)),
            tuple(sorted(writes[k], key=order.__getitem__)),
            tuple(drives[k]),
        )
        for k in range(n)
    )
    return RateGroups(groups, dict(group_of))


def multi_rate_groups(system: RobotSystem) -> RateGroups | None:
    """The rate groups of a tree whose controllers run at more than one period, else None."""
    groups = rate_groups(system)
    return groups if groups is not None and groups.multi_rate else None


def servo_period(system: RobotSystem) -> float | None:
    """The one period of a single-rate tree's controllers (their own or simulation.dt's),
    None for a multi-rate tree or a spec without tree controllers."""
    groups = rate_groups(system)
    return None if groups is None or groups.multi_rate else groups.groups[0].period
