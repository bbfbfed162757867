"""A robot system: a tree of primitive nodes (Deno et al. 1990, ch. 3).

DEFINE makes a leaf (a chain, a URDF chain, formulas, or a payload body), ATTACH joins
robots to a payload through a constraint, CONTROL puts a controller on a robot. Each node
names its children; the tree is walked the same way at every level."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from robotgen.errors import Location
from robotgen.model.chain import KinematicTree
from robotgen.model.derivatives import DerivativeSettings
from robotgen.model.expression import Expr
from robotgen.model.formula import FormulaRobot
from robotgen.model.laws.force import HybridSettings, ImpedanceSettings
from robotgen.model.laws.hand import AdaptiveSettings, ResolvedAccelerationSettings
from robotgen.model.laws.registry import LAWS
from robotgen.model.laws.resolved_rate import CompositeRateSettings, RateControlSettings
from robotgen.model.parameters import MATRIX_GAIN, Bounds
from robotgen.model.simulation import SimulationSettings


@dataclass(frozen=True, eq=False)
class PlanarBody:
    """A rigid payload moving in a plane, coordinates (x, y, psi) of its centre of mass:
    M = diag(m, m, I), C = 0, N = -m (gx, gy, 0). A payload has nil wr (§3.2)."""

    name: str
    coordinates: tuple[str, str, str]
    mass: float
    inertia: float
    gravity: np.ndarray  # (2,)
    runtime: frozenset[str] = frozenset()  # {"mass"} when the mass is a run-time parameter

    @property
    def nq(self) -> int:
        """3: x, y [m] and the angle [rad]."""
        return 3


@dataclass(frozen=True, eq=False)
class SpatialBody:
    """A rigid payload in space, coordinates (x, y, z) of its body-frame origin (at the
    centre of mass) and fixed-axis roll, pitch, yaw with R = Rz(yaw) Ry(pitch) Rx(roll), as
    URDF writes them. With omega = E(rpy) rpy_dot: M = diag(m I, E^T R I_b R^T E), C from
    Christoffel symbols, N = (-m g, 0). A payload has nil wr (§3.2)."""

    name: str
    coordinates: tuple[str, ...]  # 6
    mass: float
    inertia: np.ndarray  # (3, 3) about the centre of mass, body frame
    gravity: np.ndarray  # (3,)
    runtime: frozenset[str] = frozenset()  # {"mass"} when the mass is a run-time parameter

    @property
    def nq(self) -> int:
        """6: position [m] and orientation [rad]."""
        return 6


PAYLOAD_BODIES = (PlanarBody, SpatialBody)
Leaf = KinematicTree | FormulaRobot | PlanarBody | SpatialBody

FRAME_CHANGE = "frame_change"
PLANAR_CONTACTS = "planar_contacts"
POINT_CONTACTS = "point_contacts"
# a chain's frame_change output: its tip position (x, y, z) or its planar part (x, y)
POSITION_OUTPUT, PLANAR_OUTPUT = "position", "planar"
CHAIN_OUTPUTS = (POSITION_OUTPUT, PLANAR_OUTPUT)


@dataclass(frozen=True)
class ContactGrasp:
    """What a contact constraint needs: fingertip coordinates per contact and the payload."""

    tip_dim: int  # robot coordinates per contact (x, y or x, y, z)
    pose_dim: int  # payload coordinates
    payload: str  # how the payload is described in messages
    axes: str  # fingertip coordinates, for messages


CONTACT_GRASPS = {
    PLANAR_CONTACTS: ContactGrasp(2, 3, "a planar body (x, y, psi)", "x, y"),
    POINT_CONTACTS: ContactGrasp(3, 6, "a spatial body (6 coordinates)", "x, y, z"),
}
CONSTRAINT_FORMULAS = "formulas"
# Coulomb friction coefficient between a fingertip and the payload (a contact constraint's
# `friction`): robotgen's own model holds the fingertips bilaterally and never reads it; an
# independent simulator with unilateral contacts (robotgen.simulation.mujoco) does
DEFAULT_CONTACT_FRICTION = 1.0


@dataclass(frozen=True, eq=False)
class Constraint:
    """ATTACH's constraint J(y) ydot = G^T(x) xdot (eq 3.2) between the stacked coordinates y
    of the attached robots and the new node's coordinates x = h(y).

    frame_change:    nil payload, G = I; x = the robots' kinematic outputs (formula
                     kinematics, or a chain's tip position), J = their Jacobian.
    planar_contacts: fingertips (the robots' coordinates, 2 per contact) held at points
                     ``contacts`` of a planar payload; x = the payload's (x, y, psi);
                     J = I and G from the contact geometry. The Styx box grasp is the
                     case of two contacts at (-r, 0) and (r, 0).
    point_contacts:  the same in space: fingertips (3 coordinates each) at body-frame
                     points of a spatial payload, x = its (x, y, z, roll, pitch, yaw).
    formulas:        the user's h, h^-1 (optional), J (default I) and G as expressions;
                     y by the robots' coordinate names, x by ``coordinates``.
    """

    kind: str
    coordinates: tuple[str, ...] = ()
    output: str = POSITION_OUTPUT  # frame_change of a chain: "position" (3) or "planar" (x, y)
    contacts: np.ndarray | None = None  # (k, 2) planar_contacts, (k, 3) point_contacts
    h: tuple[Expr, ...] | None = None
    h_inverse: tuple[Expr, ...] | None = None
    J: tuple[tuple[Expr, ...], ...] | None = None
    G: tuple[tuple[Expr, ...], ...] | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    friction: float = DEFAULT_CONTACT_FRICTION  # contact constraints: fingertip-payload friction coefficient


@dataclass(frozen=True, eq=False)
class DefineNode:
    """DEFINE(M, C, N, rd, wr): a leaf robot. rd/wr are the joint state and torque ports;
    used as an ATTACH payload it has nil wr."""

    name: str
    leaf: Leaf | None  # None only inside the front end, for a URDF that failed to load (the spec is refused)

    primitive = "define"

    @property
    def children(self) -> tuple[str, ...]:
        """A DEFINE node has none."""
        return ()


@dataclass(frozen=True, eq=False)
class AttachNode:
    """ATTACH(J, G, h, payload, robot-list) (§3.3)."""

    name: str
    robots: tuple[str, ...]
    payload: str | None
    constraint: Constraint

    primitive = "attach"

    @property
    def children(self) -> tuple[str, ...]:
        """The robots, then the payload."""
        return self.robots + ((self.payload,) if self.payload else ())


# a control node's `gains`: read at run time (the default) or folded into the code
RUNTIME_GAINS, FOLDED_GAINS = "runtime", "folded"
GAIN_MODES = (RUNTIME_GAINS, FOLDED_GAINS)
# The values a tree law's gains and a payload's mass may take: the spec's, and those given at
# run time to the parameters they become (robotgen.model.parameters)
GAIN = Bounds.positive("gain", "the gain matrix must be positive definite")  # a number or a diagonal
GAIN_MATRIX = Bounds.definite("gain matrix")
# s: the time constant over which a computed-torque or feedforward controller's expected
# trajectory relaxes to the sensed state (robotgen.symbolic.control.law.integrate)
ANCHOR = 1.0
DAMPING = Bounds("damping kv_internal", minimum=0.0)  # of internal motions (eq 5.13)
PAYLOAD_MASS = Bounds("mass", minimum=0.0)


@dataclass(frozen=True, eq=False)
class ControlNode:
    """CONTROL(robot, controller) (§3.4). Gains act on the robot's external coordinates;
    ``kv_internal`` damps internal motions (eq 5.13). ``internal_forces`` resolves the
    robot's internal forces to constant values (§5.1); ``kf_internal`` and ``ki_internal``
    close a PI loop on the internal forces the robot senses (its rd force term, eqs 3.7,
    5.4-5.5), writing f_d + kf e + ki z, e = f_d - f_sensed, z its integral (controller
    state); ``resolve_internal_motion`` drives
    internal motion rates to zero (§5.2). What a controller resolves is masked from the
    levels above; what it leaves is passed up.

    ``law: resolved_rate`` (Whitney 1972) is a kinematic controller of a chain leaf or of a
    composite robot (an ATTACH node, possibly under control nodes): it has ``rate``
    settings and no gains (kp, kv are zero).

    ``period`` is the spec's sampling period of a tree law's controller, None where it takes
    its parent's (robotgen.model.rate_groups)."""

    name: str
    robot: str
    law: str
    kp: np.ndarray  # (n, n) symmetric positive definite (zero for feedforward)
    kv: np.ndarray
    kv_internal: float = 0.0
    internal_forces: np.ndarray | None = None
    kf_internal: float | None = None  # gain on the sensed internal-force error; None: no such term
    ki_internal: float | None = None  # gain on its integral [1/s]; None: no integral (no state)
    resolve_internal_motion: bool = False
    rate: RateControlSettings | CompositeRateSettings | None = None  # law resolved_rate only
    hand: ResolvedAccelerationSettings | AdaptiveSettings | None = None  # the hand laws only
    force: ImpedanceSettings | HybridSettings | None = None  # the force laws only (impedance, hybrid)
    runtime_gains: bool = True  # the gains (kp, kv, kv_internal, kf_internal, ki_internal, a force law's) are
    # run-time parameters; `gains: folded` compiles them in
    gain_forms: tuple[str, str] = (MATRIX_GAIN, MATRIX_GAIN)  # how the spec wrote kp, kv
    period: float | None = None  # seconds; None: the parent's (robotgen.model.rate_groups)
    anchor: float | None = ANCHOR  # s: the expected trajectory relaxes to the sensed state; None: open loop

    primitive = "control"

    @property
    def children(self) -> tuple[str, ...]:
        """The one robot it controls."""
        return (self.robot,)

    @property
    def hand_settings(self) -> ResolvedAccelerationSettings | AdaptiveSettings:
        """A hand law's settings (a TypeError for another law)."""
        if self.hand is None:
            raise TypeError(f"{self.name!r} has no hand settings (law {self.law})")
        return self.hand

    @property
    def acceleration(self) -> ResolvedAccelerationSettings:
        """Law resolved_acceleration's settings (a TypeError for another law)."""
        return narrowed(self.hand, ResolvedAccelerationSettings, f"the hand settings of {self.name!r}")

    @property
    def adaptive(self) -> AdaptiveSettings:
        """Law resolved_adaptive's settings (a TypeError for another law)."""
        return narrowed(self.hand, AdaptiveSettings, f"the hand settings of {self.name!r}")

    @property
    def chain_rate(self) -> RateControlSettings:
        """Law resolved_rate's settings over a chain (a TypeError otherwise)."""
        return narrowed(self.rate, RateControlSettings, f"the rate settings of {self.name!r}")

    @property
    def composite_rate(self) -> CompositeRateSettings:
        """Law resolved_rate's settings over a composite robot (a TypeError otherwise)."""
        return narrowed(self.rate, CompositeRateSettings, f"the rate settings of {self.name!r}")

    @property
    def rate_settings(self) -> RateControlSettings | CompositeRateSettings:
        """Law resolved_rate's settings (a TypeError for another law)."""
        if self.rate is None:
            raise TypeError(f"{self.name!r} has no rate settings (law {self.law})")
        return self.rate

    @property
    def impedance(self) -> ImpedanceSettings:
        """Law impedance's settings (a TypeError for another law)."""
        return narrowed(self.force, ImpedanceSettings, f"the force settings of {self.name!r}")

    @property
    def hybrid(self) -> HybridSettings:
        """Law hybrid's settings (a TypeError for another law)."""
        return narrowed(self.force, HybridSettings, f"the force settings of {self.name!r}")

    def internal_force_loop_problem(self, dt: float) -> str | None:
        """Why the internal-force PI loop is unstable at servo period ``dt`` (None: it is not, or
        there is no integral): its poles are inside the unit circle when ki_internal dt <
        2 (1 - kf_internal) (robotgen.symbolic.servo, Jury's test)."""
        if self.ki_internal is None:
            return None
        kf = self.kf_internal or 0.0
        if self.ki_internal * dt < 2 * (1 - kf):
            return None
        return (
            f"ki_internal {self.ki_internal:g} with dt = {dt:g} s: the internal-force loop needs ki_internal dt "
            f"< 2 (1 - kf_internal) = {2 * (1 - kf):g}, got {self.ki_internal * dt:g} (its poles leave the unit "
            f"circle); lower ki_internal below {2 * (1 - kf) / dt:g} or dt"
        )


Node = DefineNode | AttachNode | ControlNode
_Kind = TypeVar("_Kind")


def narrowed(value: object, kind: type[_Kind], what: str) -> _Kind:
    """``value`` as a ``kind``; a TypeError naming ``what`` if it is not one (a caller's broken
    invariant: the front end checked the spec's shape before any caller asks)."""
    if not isinstance(value, kind):
        raise TypeError(f"{what} is a {type(value).__name__}, not a {kind.__name__}")
    return value


def leaf_of(node: Node | None) -> Leaf | None:
    """The leaf of a DEFINE node; None for an ATTACH or CONTROL node (or no node)."""
    return node.leaf if isinstance(node, DefineNode) else None


def under_controls(nodes: dict[str, Node], name: str) -> DefineNode | AttachNode:
    """Node ``name`` itself, or what the chain of control nodes it heads controls."""
    node = nodes[name]
    while isinstance(node, ControlNode):
        node = nodes[node.robot]
    return node


@dataclass(frozen=True, eq=False)
class RobotSystem:
    """A robot system: the primitive tree of nodes by name, its root, the spec's settings and where it came from."""

    name: str
    source: str  # path of the spec (or URDF) it came from
    source_sha256: str
    nodes: dict[str, Node]
    root: str
    warnings: tuple[str, ...] = ()  # located, printed by the CLI; the system is still valid
    simulation: SimulationSettings | None = None  # the spec's `simulation` section
    derivatives: DerivativeSettings = DerivativeSettings()  # the spec's `derivatives` section
    dependencies: tuple[str, ...] = ()  # other files the spec reads (URDF leaves)
    node_locations: dict[str, Location] = field(default_factory=dict)  # node name -> where the spec defines it

    def location_of(self, name: str) -> Location:
        """Where node ``name`` stands in the spec (for messages found after loading)."""
        return self.node_locations.get(name, Location(self.source))

    @property
    def root_node(self) -> Node:
        """The root node."""
        return self.nodes[self.root]

    @property
    def root_control(self) -> ControlNode:
        """The root node, a CONTROL node (a TypeError if it is not)."""
        return self.control(self.root)

    def define(self, name: str) -> DefineNode:
        """Node ``name``, a DEFINE node (a TypeError if it is not)."""
        return narrowed(self.nodes[name], DefineNode, f"node {name!r}")

    def attach(self, name: str) -> AttachNode:
        """Node ``name``, an ATTACH node (a TypeError if it is not)."""
        return narrowed(self.nodes[name], AttachNode, f"node {name!r}")

    def control(self, name: str) -> ControlNode:
        """Node ``name``, a CONTROL node (a TypeError if it is not)."""
        return narrowed(self.nodes[name], ControlNode, f"node {name!r}")

    def leaf(self, name: str) -> Leaf:
        """The robot or body of DEFINE node ``name``."""
        leaf = self.define(name).leaf
        if leaf is None:
            raise TypeError(f"node {name!r} has no leaf (its URDF failed to load)")
        return leaf

    def tree(self, name: str) -> KinematicTree:
        """The kinematic tree of DEFINE node ``name`` (a TypeError if its leaf is not a chain)."""
        return narrowed(self.leaf(name), KinematicTree, f"the leaf of node {name!r}")

    @property
    def is_single_leaf(self) -> bool:
        """Whether the system is one DEFINE leaf (a chain or formulas robot alone)."""
        return isinstance(self.root_node, DefineNode)

    @property
    def root_law(self) -> str | None:
        """The law of a root controller that makes the module's functions itself (a root law,
        robotgen.model.laws.registry), else None (a leaf, or a tree of tree laws)."""
        root = self.root_node
        return root.law if isinstance(root, ControlNode) and LAWS[root.law].is_root else None

    @property
    def is_rate_controlled(self) -> bool:
        """The root is a resolved-rate controller: joint rates out, not torques."""
        return self.root_law is not None and self.root_control.rate is not None

    @property
    def rate_controls_composite(self) -> bool:
        """The root is a resolved-rate controller of a composite robot (an ATTACH tree)."""
        return self.is_rate_controlled and isinstance(self.root_control.rate, CompositeRateSettings)

    def walk(self, name: str | None = None) -> Iterator[Node]:
        """Nodes below ``name`` (default the root), children before parents."""
        node = self.nodes[name or self.root]
        for child in node.children:
            yield from self.walk(child)
        yield node
