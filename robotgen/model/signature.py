"""The coordinates of every node of a robot tree, worked out from the structure alone.

A node's velocity has external components (coordinates with positions) and internal-motion
components (rates only, §5.2); its force input has, besides the forces conjugate to those,
internal-force components (§5.1). ATTACH creates internal motions when its Jacobian has a
null space (m robot coordinates, fewer constraint rows) and internal forces when its grasp
map G has one (more contact components than node coordinates); the children's unresolved
ones are appended (eqs 5.2, 5.6). CONTROL may resolve them, masking them from above.
"""

from __future__ import annotations

from dataclasses import dataclass

from robotgen.model.chain import REVOLUTE, KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.system import (
    CONSTRAINT_FORMULAS,
    CONTACT_GRASPS,
    FRAME_CHANGE,
    PLANAR_CONTACTS,
    PLANAR_OUTPUT,
    POINT_CONTACTS,
    AttachNode,
    ControlNode,
    DefineNode,
    PlanarBody,
    RobotSystem,
    SpatialBody,
    leaf_of,
)


@dataclass(frozen=True)
class Signature:
    """A node's interface: its coordinates with positions, its rate-only internal motions, its internal forces."""

    external: tuple[str, ...]  # coordinates with positions
    internal_motions: tuple[str, ...] = ()  # rate-only coordinates
    internal_forces: tuple[str, ...] = ()

    @property
    def n_external(self) -> int:
        """The number of coordinates with positions."""
        return len(self.external)

    @property
    def n_velocity(self) -> int:
        """Dimension of the node's velocity, acceleration and (external) force vectors."""
        return len(self.external) + len(self.internal_motions)

    @property
    def n_internal_forces(self) -> int:
        """The number of internal forces."""
        return len(self.internal_forces)

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """The velocity coordinates: the external ones, then the internal motions."""
        return self.external + self.internal_motions


class SignatureError(ValueError):
    """The tree's dimensions do not fit together (reported by the spec layer with a location)."""


def leaf_coordinates(leaf) -> tuple[str, ...]:
    """A leaf's coordinate names (a chain's coordinate joints; a mimic joint has none of its own)."""
    if isinstance(leaf, KinematicTree):  # a mimic joint has no coordinate of its own
        return tuple(j.name for j in leaf.coordinate_joints)
    return tuple(leaf.coordinates)


METRE, RADIAN = "m", "rad"
UNITS = (METRE, RADIAN)
FORCE_UNITS = {METRE: "N", RADIAN: "N m", "": ""}


def leaf_units(leaf) -> tuple[str, ...]:
    """Unit of each coordinate of a leaf: a chain's revolute joints rad, prismatic m; a
    payload's pose m then rad; a formulas leaf's as its spec gives (else unknown, '')."""
    if isinstance(leaf, KinematicTree):
        return tuple(RADIAN if j.type == REVOLUTE else METRE for j in leaf.coordinate_joints)
    if isinstance(leaf, PlanarBody):
        return (METRE, METRE, RADIAN)
    if isinstance(leaf, SpatialBody):
        return (METRE,) * 3 + (RADIAN,) * 3
    return tuple(leaf.units.get(c, "") for c in leaf.coordinates)


def coordinate_units(system: RobotSystem, name: str) -> tuple[str, ...]:
    """Unit of each velocity coordinate of a node (external, then internal motions, which
    are unitless rates of a null space): '' where robotgen cannot know it."""
    node = system.nodes[name]
    sig = signature(system, name)
    internal = ("",) * len(sig.internal_motions)
    if isinstance(node, DefineNode):
        return leaf_units(node.leaf)
    if isinstance(node, ControlNode):
        return coordinate_units(system, node.robot)[: sig.n_external] + internal
    c = node.constraint
    payload = system.leaf(node.payload) if node.payload else None
    if isinstance(payload, (PlanarBody, SpatialBody)):
        external = leaf_units(payload)
    elif c.kind == FRAME_CHANGE:
        external = ()
        for r in node.robots:
            below = system.nodes[r]
            while isinstance(below, ControlNode):
                below = system.nodes[below.robot]
            leaf = system.leaf(below.name)  # a frame change's robots are leaves under their controllers
            if isinstance(leaf, FormulaRobot):
                external += tuple(leaf.units.get(o, "") for o in leaf.outputs)
            else:
                external += (METRE,) * len(chain_outputs(r, c.output))
    elif isinstance(payload, FormulaRobot):
        external = leaf_units(payload)
    else:
        external = ("",) * sig.n_external
    return external + internal


def kinematic_outputs(system: RobotSystem, name: str) -> tuple[str, ...]:
    """Names of a robot's kinematic outputs, the coordinates a frame_change ATTACH gives it."""
    node = system.nodes[name]
    while isinstance(node, ControlNode):
        node = system.nodes[node.robot]
    if isinstance(node, DefineNode) and isinstance(node.leaf, FormulaRobot):
        if not node.leaf.kinematics:
            raise SignatureError(f"robot '{name}' has no kinematics for a frame_change")
        return node.leaf.outputs
    if isinstance(node, DefineNode) and isinstance(node.leaf, KinematicTree):
        return ()  # decided by the constraint's ``output`` (position or planar)
    raise SignatureError(f"robot '{name}' is not a leaf with kinematics; frame_change needs one")


def chain_outputs(name: str, output: str) -> tuple[str, ...]:
    """A chain output's coordinate names: <name>_x, _y (planar) and _z."""
    axes = ("x", "y") if output == PLANAR_OUTPUT else ("x", "y", "z")
    return tuple(f"{name}_{a}" for a in axes)


def signature(system: RobotSystem, name: str) -> Signature:
    """The signature of node ``name``: a leaf's coordinates, or what its constraint or controller leaves unresolved."""
    node = system.nodes[name]
    if isinstance(node, DefineNode):
        return Signature(leaf_coordinates(node.leaf))
    if isinstance(node, ControlNode):
        child = signature(system, node.robot)
        forces = () if node.internal_forces is not None else child.internal_forces
        motions = () if node.resolve_internal_motion else child.internal_motions
        return Signature(child.external, motions, forces)
    return _attach_signature(system, node)


def _attach_structure(system: RobotSystem, node: AttachNode) -> tuple[tuple[str, ...], int, int]:
    """(the node's coordinates, how many internal motions and internal forces it creates)."""
    children = [signature(system, r) for r in node.robots]
    m = sum(c.n_external for c in children)
    c = node.constraint
    external: tuple[str, ...]
    if c.kind == FRAME_CHANGE:
        external = ()
        for r in node.robots:
            outputs = kinematic_outputs(system, r)
            external += outputs or chain_outputs(r, c.output)
        rows = len(external)  # J is (outputs x m), G = I
        n_forces = 0
    elif c.kind in CONTACT_GRASPS:
        grasp = CONTACT_GRASPS[c.kind]
        payload = system.leaf(node.payload) if node.payload else None
        if payload is None or len(leaf_coordinates(payload)) != grasp.pose_dim:
            raise SignatureError(f"{c.kind} on '{node.name}' needs a payload: {grasp.payload}")
        if c.contacts is None:
            raise SignatureError(f"{c.kind} on '{node.name}' needs its contact points")
        external = leaf_coordinates(payload)
        if m != grasp.tip_dim * len(c.contacts):
            raise SignatureError(
                f"attach '{node.name}': {len(c.contacts)} contacts need "
                f"{grasp.tip_dim * len(c.contacts)} robot coordinates (fingertip "
                f"{grasp.axes} each), got {m}"
            )
        rows = m  # J = I
        n_forces = m - grasp.pose_dim
    elif c.kind == CONSTRAINT_FORMULAS:
        external = c.coordinates
        rows = len(c.J) if c.J is not None else m
        n_forces = rows - len(external)
    else:
        raise SignatureError(f"unknown constraint kind '{c.kind}'")
    n_motions = m - rows
    if n_motions < 0 or n_forces < 0:
        raise SignatureError(
            f"attach '{node.name}': {m} robot coordinates, {rows} constraint rows and "
            f"{len(external)} node coordinates do not fit (need m >= rows >= n)"
        )
    return external, n_motions, n_forces


def _attach_signature(system: RobotSystem, node: AttachNode) -> Signature:
    external, n_motions, n_forces = _attach_structure(system, node)
    motions, forces = created_names(node, n_motions, n_forces)
    for ch in (signature(system, r) for r in node.robots):
        motions += ch.internal_motions
        forces += ch.internal_forces
    return Signature(external, motions, forces)


def created_names(node: AttachNode, n_motions: int, n_forces: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names of the internal motions and forces an ATTACH creates: <node>_m1.., <node>_f1.."""
    return (
        tuple(f"{node.name}_m{k + 1}" for k in range(n_motions)),
        tuple(f"{node.name}_f{k + 1}" for k in range(n_forces)),
    )


def robot_leaves(system: RobotSystem, name: str | None = None) -> list[str]:
    """The actuated leaves below a node, in tree order: their joint states are the sensed
    state of the whole system (payloads are not actuated and not sensed)."""
    node = system.nodes[name or system.root]
    if isinstance(node, DefineNode):
        return [node.name]
    robots = node.robots if isinstance(node, AttachNode) else (node.robot,)
    return [leaf for r in robots for leaf in robot_leaves(system, r)]


def angle_coordinates(system: RobotSystem, name: str) -> tuple[bool, ...]:
    """Which external coordinates of a node are known to be angles (a position error in them
    wraps to (-pi, pi]). Only a rigid pose is known: the node coordinates a planar_contacts or
    point_contacts attach computes from the contact geometry (psi; roll, pitch, yaw), or those
    of a rigid_body payload, which are the node's. A frame change's outputs, formula
    constraints with other payloads and leaf coordinates are not classified: no wrapping."""
    node = system.nodes[name]
    while isinstance(node, ControlNode):
        node = system.nodes[node.robot]
    n = signature(system, node.name).n_external
    if not isinstance(node, AttachNode):
        return (False,) * n
    payload = system.leaf(node.payload) if node.payload else None
    if node.constraint.kind == PLANAR_CONTACTS or isinstance(payload, PlanarBody):
        return (False, False, True) if n == 3 else (False,) * n
    if node.constraint.kind == POINT_CONTACTS or isinstance(payload, SpatialBody):
        return (False,) * 3 + (True,) * 3 if n == 6 else (False,) * n
    return (False,) * n


def has_position_inverse(system: RobotSystem, node: AttachNode) -> bool:
    """Whether an ATTACH knows h^-1 (robot positions from its own): contact grasps always,
    formula constraints when they give h_inverse, frame changes when every robot is a
    formulas leaf with inverse_kinematics."""
    c = node.constraint
    if c.kind in CONTACT_GRASPS:
        return True
    if c.kind == CONSTRAINT_FORMULAS:
        return c.h_inverse is not None
    leaves = []
    for r in node.robots:
        below = system.nodes[r]
        while isinstance(below, ControlNode):
            below = system.nodes[below.robot]
        leaves.append(leaf_of(below))
    return all(isinstance(leaf, FormulaRobot) and leaf.inverse_kinematics for leaf in leaves)


def constraint_residual_names(system: RobotSystem) -> list[str]:
    """Entries of the position-level constraint residual y - h^-1(h(y)): for every ATTACH
    with h^-1 (in walk order), its robots' external coordinates, as <attach>.<coordinate>."""
    names = []
    for node in system.walk():
        if isinstance(node, AttachNode) and has_position_inverse(system, node):
            names += [f"{node.name}.{c}" for r in node.robots for c in signature(system, r).external]
    return names


def internal_force_names(system: RobotSystem) -> list[str]:
    """The internal forces every ATTACH creates (whether or not a controller resolves
    them), in walk order: what the plant's internal-force readback reports."""
    names: list[str] = []
    for node in system.walk():
        if isinstance(node, AttachNode):
            _, n_motions, n_forces = _attach_structure(system, node)
            names += created_names(node, n_motions, n_forces)[1]
    return names
