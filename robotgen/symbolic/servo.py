"""The wr attributes of a robot tree, composed into one servo step (Deno et al. 1990):
a desired trajectory written at a node flows down through CONTROL (§3.4, eq 2.10) and
ATTACH (eqs 3.8, 5.3, 5.9) to the leaves, whose wr drives the actuators with the torque
that reaches them. Every controller in the tree is evaluated on the way, in order.

Each CONTROL node's law (robotgen.symbolic.control) turns what is written at it into the
force on its robot. A controller with ``kf_internal`` closes a loop on the internal forces
its robot senses: rd's force term (eq 3.7), the leaves' sensed forces tau_sensed carried up
by inverting each ATTACH's force map (eq 5.4), so that it writes f_d + kf (f_d - f_sensed)
instead of f_d; the step then takes tau_sensed. Stateful laws (computed torque, feedforward) integrate an expected
trajectory (x_e, xd_e) from xdd_e (§3.4); that is their state, passed in and out of the
step (the emitted C keeps no state of its own)."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.system import AttachNode, ControlNode, DefineNode
from robotgen.symbolic.control.gains import gain, kf_internal, kv_internal
from robotgen.symbolic.control.law import Command, PositionsUnavailable
from robotgen.symbolic.control.tree_laws import TREE_LAWS
from robotgen.symbolic.rows import rows
from robotgen.symbolic.system import SystemGraphs


@dataclass(frozen=True, eq=False)
class Trajectory:
    """What wr carries, in the receiving node's coordinates (eq 5.1)."""

    x: ca.SX | None  # external positions; None when no h^-1 lets them through
    v: ca.SX
    a: ca.SX
    F: ca.SX
    Fi: ca.SX  # internal forces


def stateful_controllers(graphs: SystemGraphs, name: str) -> list[ControlNode]:
    """Controllers with an integrated expected trajectory below ``name``, in walk order."""
    return [n for n in graphs.system.walk(name) if isinstance(n, ControlNode) and TREE_LAWS[n.law].stateful]


class Servo:
    """Builds the write of one node: the leaf torques and next controller states.

    ``controllers`` (default: every stateful one below ``top``) are those whose states this
    step carries; ``period`` folds the servo period in as a constant instead of the input dt
    (a rate group's step, robotgen.symbolic.rate_steps)."""

    def __init__(self, graphs: SystemGraphs, top: str, controllers: list[ControlNode] | None = None,
                 period: float | None = None):
        self.g = graphs
        self.controllers = stateful_controllers(graphs, top) if controllers is None else controllers
        self.layout: dict[str, tuple[int, int, int]] = {}  # name -> (offset, n_x, n_v)
        o = 0
        for c in self.controllers:
            sig = graphs.graph(c.robot).sig
            self.layout[c.name] = (o, sig.n_external, sig.n_velocity)
            o += sig.n_external + sig.n_velocity
        self.n_state = o
        self.state = ca.SX.sym("state", o)
        self.dt = ca.SX.sym("dt") if period is None else ca.SX(period)
        self.torques: dict[str, ca.SX] = {}
        self.next_state: dict[str, ca.SX] = {}
        # the leaves' sensed forces (rd of a DEFINE, §3.2), read when a controller below closes
        # a loop on sensed internal forces
        self.reads_forces = reads_sensed_forces(graphs, top)
        self.tau_sensed = ca.SX.sym("tau_sensed", graphs.n)
        self._sensed: dict[str, tuple[ca.SX, ca.SX]] = {}

    def initial_state(self) -> ca.SX:
        """Expected trajectories start at the controlled robots' current state."""
        parts = []
        for c in self.controllers:
            child = self.g.graph(c.robot)
            parts += [child.x, child.v]
        return ca.vertcat(*parts) if parts else ca.SX(0, 1)

    def tau(self) -> ca.SX:
        return ca.vertcat(*[self.torques.get(leaf, ca.SX.zeros(self.g.sizes[leaf]))
                            for leaf in self.g.leaves])

    def state_next(self) -> ca.SX:
        return ca.vertcat(*[self.next_state[c.name] for c in self.controllers]) if self.controllers else ca.SX(0, 1)

    def write(self, name: str, t: Trajectory) -> None:
        node = self.g.system.nodes[name]
        if isinstance(node, DefineNode):
            self.torques[name] = t.F  # a torque-driven leaf applies the force it is sent
        elif isinstance(node, ControlNode):
            self._control(node, t)
        else:
            self._attach(node, t)

    # -- CONTROL ---------------------------------------------------------------------
    def _control(self, node: ControlNode, t: Trajectory) -> None:
        """The law's write (robotgen.symbolic.control) on the controlled robot's coordinates."""
        child = self.g.graph(node.robot)
        sc = child.sig
        ne, nvc = sc.n_external, sc.n_velocity
        pad = nvc - t.v.shape[0]  # internal motions this controller resolves: desired rate 0
        v_d = ca.vertcat(t.v, ca.SX.zeros(pad))
        a_d = ca.vertcat(t.a, ca.SX.zeros(pad))
        F_d = ca.vertcat(t.F, ca.SX.zeros(pad))
        Fi = ca.SX(ca.DM(node.internal_forces)) if node.internal_forces is not None else t.Fi
        parameters = self.g.parameters
        if node.kf_internal is not None:  # the internal-force loop on the robot's rd force term
            Fi = Fi + kf_internal(node, parameters) * (Fi - self.sensed(node.robot)[1])
        Kp, Kv, kvi = gain(node, "kp", parameters), gain(node, "kv", parameters), kv_internal(node, parameters)
        e_dot = v_d - child.v

        def feedback(e: ca.SX | None) -> ca.SX:
            """Kv e' + Kp e on external coordinates, kv_internal e' on internal ones (eq 5.13)."""
            ext = Kv @ rows(e_dot, 0, ne) + (Kp @ e if e is not None else 0)
            return ca.vertcat(ext, kvi * rows(e_dot, ne))

        def position_error() -> ca.SX:
            if t.x is None:
                raise PositionsUnavailable(
                    f"controller '{node.name}' needs desired positions, but an attach above it has no "
                    "inverse kinematics (give the robots inverse_kinematics or the constraint h_inverse)")
            return t.x - child.x

        law = TREE_LAWS[node.law]
        expected = None
        if law.stateful:
            o, nx, nv = self.layout[node.name]
            expected = (rows(self.state, o, o + nx), rows(self.state, o + nx, o + nx + nv))
        out = law.write(Command(child, v_d, a_d, F_d, feedback, position_error, t.x, expected, self.dt))
        if law.stateful:
            self.next_state[node.name] = out.next_expected
        self.write(node.robot, Trajectory(out.x, out.v, out.a, out.F, Fi))

    # -- ATTACH ----------------------------------------------------------------------
    def _attach(self, node: AttachNode, t: Trajectory) -> None:
        g = self.g.graph(node.name)
        maps = g.attach
        ne, m1, f1 = g.sig.n_external, maps.n_created_motions, maps.n_created_forces
        w = maps.A @ t.v  # eq 3.8: children velocities
        wa = maps.A @ t.a + maps.Adot @ t.v  # and accelerations
        tau_e = maps.D @ ca.vertcat(rows(t.F, 0, ne), rows(t.F, ne, ne + m1), rows(t.Fi, 0, f1))  # eqs 5.3, 5.9
        F_int, Fi_int = rows(t.F, ne + m1), rows(t.Fi, f1)  # the children's own, passed down
        y = maps.h_inverse(t.x) if (t.x is not None and maps.h_inverse is not None) else None
        row = e0 = i0 = fi0 = 0
        for r in node.robots:
            sc = self.g.graph(r).sig
            ne_c, nv_c, nf_c = sc.n_external, sc.n_velocity, sc.n_internal_forces
            ni_c = nv_c - ne_c
            F_c = ca.vertcat(rows(tau_e, e0, e0 + ne_c), rows(F_int, i0, i0 + ni_c))
            self.write(r, Trajectory(
                rows(y, e0, e0 + ne_c) if y is not None else None,
                rows(w, row, row + nv_c), rows(wa, row, row + nv_c), F_c, rows(Fi_int, fi0, fi0 + nf_c)))
            row, e0, i0, fi0 = row + nv_c, e0 + ne_c, i0 + ni_c, fi0 + nf_c

    # -- rd's force term ----------------------------------------------------------------
    def sensed(self, name: str) -> tuple[ca.SX, ca.SX]:
        """(F, F_i): the forces node ``name`` senses, in its velocity coordinates and its
        internal forces, from the leaves' tau_sensed. A leaf senses its own; a controlled
        robot the robot's (§3.4: rd passes through, less what the controller resolves); an
        ATTACH splits its robots' stacked external forces by the inverse of its force map D
        (eq 5.4; with a square J this is A^T tau_R, eq 3.7, and H J^-T tau_R, eq 5.5) and
        appends their internal motions' forces and internal forces."""
        if name not in self._sensed:
            node = self.g.system.nodes[name]
            sig = self.g.graph(name).sig
            if isinstance(node, DefineNode):
                out = (self.tau_sensed[self.g.leaf_slice(name)], ca.SX(0, 1))
            elif isinstance(node, ControlNode):
                F, Fi = self.sensed(node.robot)
                out = (rows(F, 0, sig.n_velocity), Fi if sig.n_internal_forces else ca.SX(0, 1))
            else:
                maps = self.g.graph(name).attach
                parts = [self.sensed(r) for r in node.robots]
                kids = [self.g.graph(r).sig for r in node.robots]
                tau_e = ca.vertcat(*[rows(F, 0, k.n_external) for (F, _), k in zip(parts, kids)])
                split = ca.solve(maps.D, tau_e)  # [F_e; F_m1; F_i1]
                f1 = maps.n_created_forces
                n_motion = sig.n_external + maps.n_created_motions
                F = ca.vertcat(rows(split, 0, n_motion), *[rows(F, k.n_external) for (F, _), k in zip(parts, kids)])
                Fi = ca.vertcat(rows(split, n_motion, n_motion + f1), *[Fi for _, Fi in parts])
                out = (F, Fi)
            self._sensed[name] = out
        return self._sensed[name]


def reads_sensed_forces(graphs: SystemGraphs, name: str) -> bool:
    """A controller at or below ``name`` closes a loop on sensed internal forces."""
    return any(isinstance(n, ControlNode) and n.kf_internal is not None for n in graphs.system.walk(name))
