"""The wr attributes of a robot tree, composed into one servo step (Deno et al. 1990):
a desired trajectory written at a node flows down through CONTROL (§3.4, eq 2.10) and
ATTACH (eqs 3.8, 5.3, 5.9) to the leaves, whose wr drives the actuators with the torque
that reaches them. Every controller in the tree is evaluated on the way, in order.

Each CONTROL node's law (robotgen.symbolic.control) turns what is written at it into the
force on its robot. rd's force term (eq 3.7) reaches a controller that asks for it: the
leaves' sensed forces tau_sensed (what each leaf exerts on what it touches, in its joint
coordinates) carried up by inverting each ATTACH's force map (eq 5.4), so that a node senses
F_s on its velocity coordinates and F_i,s on its internal forces (eq 5.5); the step then
takes tau_sensed. A controller with ``kf_internal`` or ``ki_internal`` closes a PI loop on
its robot's internal forces: it writes f_d + kf e + ki z, e = f_d - F_i,s, z the integral of
e; a law may read F_s (impedance, hybrid force/position control). Stateful laws integrate
an expected trajectory (x_e, xd_e) from xdd_e (§3.4) or a force error; that state and the
internal-force integrals are the controller state, passed in and out of the step (the
emitted C keeps no state of its own)."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.system import AttachNode, ControlNode, DefineNode
from robotgen.symbolic.control.gains import gain, internal_force_gain, kv_internal
from robotgen.symbolic.control.law import Command, PositionsUnavailable
from robotgen.symbolic.control.tree_laws import tree_law
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


LAW_STATE, FORCE_INTEGRAL = "law", "internal_force_integral"


def keeps_state(node: ControlNode) -> bool:
    """The controller has a block of state (state_blocks): its law's, or its force integral's."""
    return tree_law(node.law).state is not None or node.ki_internal is not None


def state_blocks(graphs: SystemGraphs, name: str) -> list[tuple[ControlNode, str, ca.SX]]:
    """The controller state below ``name``, block by block in walk order: (controller, kind,
    the block's value after a reset). A stateful law's own state (LAW_STATE), then the
    integral of the internal-force error of a controller with ki_internal (FORCE_INTEGRAL,
    zero after a reset)."""
    out = []
    for n in graphs.system.walk(name):
        if not isinstance(n, ControlNode):
            continue
        law = tree_law(n.law)
        if law.state is not None:  # (law.stateful)
            out.append((n, LAW_STATE, law.state(graphs.graph(n.robot))))
        if n.ki_internal is not None:
            out.append((n, FORCE_INTEGRAL, ca.SX.zeros(graphs.graph(n.robot).sig.n_internal_forces)))
    return out


class Servo:
    """Builds the write of one node: the leaf torques and next controller states.

    ``controllers`` (default: every one below ``top``) are the names of those whose states
    this step carries; ``period`` folds the servo period in as a constant instead of the input dt
    (a rate group's step, robotgen.symbolic.rate_steps)."""

    def __init__(
        self, graphs: SystemGraphs, top: str, controllers: set[str] | None = None, period: float | None = None
    ):
        self.g = graphs
        self.blocks = [b for b in state_blocks(graphs, top) if controllers is None or b[0].name in controllers]
        self.layout: dict[tuple[str, str], tuple[int, int]] = {}  # (controller, kind) -> (offset, size)
        o = 0
        for node, kind, start in self.blocks:
            self.layout[node.name, kind] = (o, start.shape[0])
            o += start.shape[0]
        self.n_state = o
        self.state = ca.SX.sym("state", o)
        self.dt = ca.SX.sym("dt") if period is None else ca.SX(period)
        self.torques: dict[str, ca.SX] = {}
        self.next_state: dict[tuple[str, str], ca.SX] = {}
        # the leaves' sensed forces (rd of a DEFINE, §3.2), read when a controller below closes
        # a loop on sensed internal forces or has a law that reads forces
        self.reads_forces = any(
            isinstance(n, ControlNode) and reads_forces(n) and (controllers is None or n.name in controllers)
            for n in graphs.system.walk(top)
        )
        self.tau_sensed = ca.SX.sym("tau_sensed", graphs.n)
        self._sensed: dict[str, tuple[ca.SX, ca.SX]] = {}

    def initial_state(self) -> ca.SX:
        """Expected trajectories start at the controlled robots' current state, integrals at zero."""
        return ca.vertcat(*[start for _, _, start in self.blocks]) if self.blocks else ca.SX(0, 1)

    def block(self, node: ControlNode, kind: str) -> ca.SX:
        """A controller's state block ``kind`` (integral, expected trajectory) in the step's state vector."""
        o, n = self.layout[node.name, kind]
        return rows(self.state, o, o + n)

    def tau(self) -> ca.SX:
        """Every leaf's torques, stacked in leaf order (zero for a leaf nothing drives)."""
        return ca.vertcat(*[self.torques.get(leaf, ca.SX.zeros(self.g.sizes[leaf])) for leaf in self.g.leaves])

    def state_next(self) -> ca.SX:
        """The next controller state, block by block in the state's order."""
        if not self.blocks:
            return ca.SX(0, 1)
        return ca.vertcat(*[self.next_state[node.name, kind] for node, kind, _ in self.blocks])

    def write(self, name: str, t: Trajectory) -> None:
        """Write trajectory ``t`` to node ``name``: a leaf's torques, a controller's law, an ATTACH's distribution."""
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
        if node.kf_internal is not None or node.ki_internal is not None:
            Fi = self._internal_force_loop(node, Fi)
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
                    "inverse kinematics (give the robots inverse_kinematics or the constraint h_inverse)"
                )
            return t.x - child.x

        law = tree_law(node.law)
        state = self.block(node, LAW_STATE) if law.stateful else None
        out = law.write(
            Command(
                child,
                v_d,
                a_d,
                F_d,
                feedback,
                position_error,
                t.x,
                state,
                self.dt,
                node,
                parameters,
                lambda: self.sensed(node.robot),
            )
        )
        if law.stateful:
            if out.next_state is None:
                raise TypeError(f"law {node.law} keeps a state and wrote no next one")
            self.next_state[node.name, LAW_STATE] = out.next_state
        self.write(node.robot, Trajectory(out.x, out.v, out.a, out.F, Fi))

    def _internal_force_loop(self, node: ControlNode, f_d: ca.SX) -> ca.SX:
        """The internal forces a controller writes with its PI loop on those its robot senses
        (eq 5.5's H J^-T tau_R part, carried up): f_d + kf e + ki z_next, e = f_d - F_i,s and
        z_next = z + dt e; the correction goes down through the force maps of eqs 5.2-5.3
        like any internal force. F_i,s is the force carried during the last period, so with a
        grasp that carries what it is sent at once, f(k) = f_d + kf e(k) + ki z(k+1) + d with
        e(k) = f_d - f(k-1): characteristic polynomial q^2 + (kf - 1 + ki dt) q - kf, stable
        for 0 <= kf < 1 and 0 < ki dt < 2 (1 - kf) (Jury), and a constant disturbance d is
        removed when ki > 0."""
        kf, ki = (
            internal_force_gain(node, "kf_internal", self.g.parameters),
            internal_force_gain(node, "ki_internal", self.g.parameters),
        )
        error = f_d - self.sensed(node.robot)[1]
        out = f_d + kf * error if kf is not None else f_d
        if ki is not None:
            z_next = self.block(node, FORCE_INTEGRAL) + self.dt * error
            self.next_state[node.name, FORCE_INTEGRAL] = z_next
            out = out + ki * z_next
        return out

    # -- ATTACH ----------------------------------------------------------------------
    def _attach(self, node: AttachNode, t: Trajectory) -> None:
        g = self.g.graph(node.name)
        maps = g.maps
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
            self.write(
                r,
                Trajectory(
                    rows(y, e0, e0 + ne_c) if y is not None else None,
                    rows(w, row, row + nv_c),
                    rows(wa, row, row + nv_c),
                    F_c,
                    rows(Fi_int, fi0, fi0 + nf_c),
                ),
            )
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
                maps = self.g.graph(name).maps
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
    """A controller at or below ``name`` reads sensed forces: a loop on internal forces, or a
    law that reads its robot's (the servo step then takes tau_sensed)."""
    return any(isinstance(n, ControlNode) and reads_forces(n) for n in graphs.system.walk(name))


def reads_forces(node: ControlNode) -> bool:
    """The controller closes a loop on internal forces or its law reads its robot's forces."""
    return node.kf_internal is not None or node.ki_internal is not None or tree_law(node.law).reads_forces(node)
