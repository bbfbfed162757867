"""One servo step per rate group of a multi-rate tree (robotgen.model.rate_groups).

Group k's step ``servo_step_g<k>`` evaluates the wr attributes of its own controllers as the
fused servo_step does (robotgen.symbolic.servo), from where its part of the tree starts: the
root trajectory, if the group has controllers (or, the fastest, uncontrolled leaves) below
the root without a controller between, and the held trajectory ``wr_<node>`` at each of its
controllers that a slower one writes to. Where one of its controllers writes to a faster
group's controller it stops and returns that trajectory as ``wr_<node>``, which the caller
holds (zero-order hold) until the group's next tick. Its outputs are the torques of the
leaves it drives (zero for the others: each leaf is driven by one group, so the actuators'
torques are the sum of every group's last torques), the trajectories it writes down, and its
controllers' next states; its period is folded in as the stateful laws' dt.

A held trajectory is [x_e; xd_e; xdd_e; F_e; F_i] in the receiving controller's coordinates
(eq 5.1), x_e left out where no ATTACH above has h^-1."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.rate_groups import RateGroups
from robotgen.model.system import ControlNode, DefineNode, RobotSystem
from robotgen.symbolic.kernel import Kernel, make_kernel
from robotgen.symbolic.rows import rows
from robotgen.symbolic.servo import Servo, Trajectory, keeps_state
from robotgen.symbolic.system import SystemGraphs

STEP, INIT = "servo_step_g{}", "servo_init_g{}"
HELD = "wr_{}"  # the port of a held trajectory, by the controller it is written to


@dataclass(frozen=True)
class HeldLayout:
    """Where a held trajectory's parts are in its vector."""

    n_x: int  # 0 when no h^-1 above lets positions through
    n_v: int
    n_fi: int

    @property
    def size(self) -> int:
        """The held vector's length: x, v, a, F and the internal forces."""
        return self.n_x + 3 * self.n_v + self.n_fi

    def vector(self, t: Trajectory) -> ca.SX:
        """A trajectory as the held vector."""
        return ca.vertcat(*([t.x] if self.n_x and t.x is not None else []), t.v, t.a, t.F, t.Fi)

    def trajectory(self, held: ca.SX) -> Trajectory:
        """The trajectory a held vector holds."""
        x, v0 = (rows(held, 0, self.n_x), self.n_x) if self.n_x else (None, 0)
        v, a, F = (rows(held, v0 + i * self.n_v, v0 + (i + 1) * self.n_v) for i in range(3))
        return Trajectory(x, v, a, F, rows(held, v0 + 3 * self.n_v))


class GroupServo(Servo):
    """The write of one rate group: its controllers evaluated, the others' skipped, the
    trajectories it writes to a faster group's controllers kept in ``written``."""

    def __init__(self, graphs: SystemGraphs, groups: RateGroups, k: int):
        root = graphs.system.root
        own = set(groups.groups[k].controllers)
        super().__init__(graphs, root, controllers=own, period=groups.groups[k].period)
        self.groups, self.k = groups, k
        self.below = False  # a controller of this group is above the node being written
        self.written: dict[str, Trajectory] = {}

    def write(self, name: str, t: Trajectory) -> None:
        """Write ``t`` to node ``name``; a faster group's controller gets it held, another group's work is skipped."""
        node = self.g.system.nodes[name]
        if isinstance(node, ControlNode):
            g = self.groups.group_of[name]
            if g != self.k:
                if self.below:  # a faster group's controller: what it is sent is held for it
                    self.written[name] = t
                return  # (below the root without a controller between: that group's own work)
            below, self.below = self.below, True
            self._control(node, t)
            self.below = below
        elif isinstance(node, DefineNode):
            if self.below or self.k == 0:  # a leaf no controller drives: the fastest group's
                self.torques[name] = t.F
        else:
            self._attach(node, t)


def rate_kernels(g: SystemGraphs, groups: RateGroups) -> list[Kernel]:
    """servo_step_g<k> for every group, fastest first, then servo_init_g<k> for every group
    with a stateful controller."""
    system = g.system
    root_sig = g.graph(system.root).sig
    layouts: dict[str, HeldLayout] = {}
    steps: list[Kernel] = []
    inits: list[Kernel] = []
    for group in reversed(groups.groups):  # the slowest first: a reader needs its writer's layout
        k = group.index
        servo = GroupServo(g, groups, k)
        inputs = [("theta", g.theta), ("theta_dot", g.theta_dot)]
        if group.reads_root:
            x_e = ca.SX.sym("x_e", root_sig.n_external)
            xd_e, xdd_e, f_e = (ca.SX.sym(s, root_sig.n_velocity) for s in ("xd_e", "xdd_e", "f_e"))
            f_i = ca.SX.sym("f_i", root_sig.n_internal_forces)
            inputs += [("x_e", x_e), ("xd_e", xd_e), ("xdd_e", xdd_e), ("f_e", f_e)]
            if root_sig.n_internal_forces:
                inputs.append(("f_i", f_i))
            servo.write(system.root, Trajectory(x_e, xd_e, xdd_e, f_e, f_i))
        for name in group.reads:
            held = ca.SX.sym(HELD.format(name), layouts[name].size)
            inputs.append((HELD.format(name), held))
            servo.write(name, layouts[name].trajectory(held))
        if servo.reads_forces:
            inputs.append(("tau_sensed", servo.tau_sensed))
        outputs = [("tau", servo.tau(), (g.n, 1))]
        for name in group.writes:
            t = servo.written[name]
            sig = g.graph(name).sig
            layouts[name] = HeldLayout(sig.n_external if t.x is not None else 0, sig.n_velocity, sig.n_internal_forces)
            outputs.append((HELD.format(name), layouts[name].vector(t), (layouts[name].size, 1)))
        if servo.n_state:
            inputs.append(("state", servo.state))
            outputs.append(("state_next", servo.state_next(), (servo.n_state, 1)))
        read = (
            ["sensed leaf states"]
            + (["the desired root trajectory"] if group.reads_root else [])
            + ([f"the trajectories held at {', '.join(group.reads)}"] if group.reads else [])
        )
        given = (
            [
                f"the torques of the leaves it drives ({', '.join(group.drives)}; 0 for the others)"
                if group.drives
                else "tau 0 (faster groups drive the leaves below it)"
            ]
            + ([f"the trajectories it writes to {', '.join(group.writes)}"] if group.writes else [])
            + (["its controllers' next state"] if servo.n_state else [])
        )
        every = f"{group.ticks} periods of group 0" if k else "the fastest"
        steps.append(
            make_kernel(
                STEP.format(k),
                f"One step of rate group {k} ({', '.join(group.controllers)}), every {group.period:g} s "
                f"({every}): {', '.join(read)} in; {', '.join(given)} out.",
                inputs,
                outputs,
                g.parameters,
                guarded=True,
            )
        )
        if servo.n_state:
            inits.append(
                make_kernel(
                    INIT.format(k),
                    f"Controller state of rate group {k} that starts its expected trajectories at the current state.",
                    [("theta", g.theta), ("theta_dot", g.theta_dot)],
                    [("state", servo.initial_state(), (servo.n_state, 1))],
                    g.parameters,
                )
            )
    return [*reversed(steps), *reversed(inits)]


@dataclass(frozen=True)
class GroupStep:
    """One rate group as the module's MultiRateController runs it."""

    step: str  # kernel names
    init: str | None  # None: no stateful controller in the group
    period: float
    ticks: int
    controllers: tuple[str, ...]


@dataclass(frozen=True)
class MultiRate:
    """The controller that runs a multi-rate tree's group steps on one tick count of the
    fastest period (robotgen.emit.multirate): a C struct holding every group's state, the held
    trajectories and each group's last torques, and a class in the Python extension.

    At tick t every group whose ticks divide t runs, the slowest first, so that what a slower
    group writes at t is held for the faster ones from t on; the torques are the sum of each
    group's last. On the first step after a reset every group's init runs first."""

    class_name: str
    groups: tuple[GroupStep, ...]  # fastest first
    held: tuple[str, ...]  # the held trajectories' ports (wr_<node>), in the order they are written
    single_rate: str = "servo_step"  # the fused step of the same tree, every controller at one rate

    @property
    def frame_ticks(self) -> int:
        """The slowest group's ticks: fastest periods in one frame."""
        return self.groups[-1].ticks


MULTI_RATE_CLASS = "MultiRateController"


def multi_rate(system: RobotSystem, groups: RateGroups) -> MultiRate:
    """The MultiRateController of ``system`` with these groups."""

    def stateful(k: int) -> bool:
        return any(keeps_state(system.control(name)) for name in groups.groups[k].controllers)

    return MultiRate(
        MULTI_RATE_CLASS,
        tuple(
            GroupStep(
                STEP.format(g.index),
                INIT.format(g.index) if stateful(g.index) else None,
                g.period,
                g.ticks,
                g.controllers,
            )
            for g in groups.groups
        ),
        tuple(HELD.format(name) for name in groups.boundaries),
    )
