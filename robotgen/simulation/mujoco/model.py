"""A robotgen system written as an MJCF model of the same bodies, and the maps between the two.

What becomes what:

- a chain or URDF leaf (``KinematicTree``): nested bodies, one per joint (body frame = the
  joint's frame, ``pos``/``quat`` its origin in the parent's), a hinge or slide joint at
  the body origin with the joint's axis, ``armature`` (the motor inertia times the gear
  ratio squared, which MuJoCo also adds to M's diagonal), ``damping`` = the viscous
  coefficient, and the link's ``inertial`` (mass, centre of mass, principal moments and
  axes of its inertia tensor);
- a formulas leaf: the same from its ``mechanism``, a chain whose joint positions q give
  the leaf's coordinates theta = T q + offset; each coordinate is a fixed tendon with T's
  row as coefficients, so that a torque on it acts on the joints as T^T tau;
- every leaf coordinate gets a motor (gear 1) on its joint or tendon: ctrl is robotgen's tau;
- a planar payload: slide x, slide y, hinge z (its coordinates x, y, psi); a spatial one
  a free joint (its frame at the centre of mass, as robotgen's);
- the simulation's wall: a plane in the world whose face lies FINGERTIP_RADIUS inside the
  wall's, touched only by a sphere of that radius centred on the tip of the leaf whose point
  the wall's node is (a frame change of one leaf, or the leaf itself); frictionless (condim
  1), MuJoCo's soft contact with the grasps' time constant, not robotgen's spring;
- a planar_contacts or point_contacts grasp: a sphere of radius FINGERTIP_RADIUS centred
  on each fingertip (the leaf's tip frame) and a flat pad on the payload whose face lies
  FINGERTIP_RADIUS inside the contact point, facing out along the line from the payload's
  centre through the point; each tip touches only its pad (an explicit contact pair, elliptic
  friction cone, condim 3, the constraint's ``friction``; MuJoCo's noslip solver keeps a held
  payload from creeping). Where robotgen holds the tip on the point bilaterally, the pad pushes
  but does not pull, and holds tangentially only inside the friction cone.

What cannot be mapped, and what is done instead:

- Coulomb friction: robotgen's is the smooth coulomb tanh(qd / smoothing), part of N.
  MuJoCo's ``frictionloss`` is a dry-friction constraint (set-valued at rest, solved with
  the contacts) and no MJCF attribute is a tanh, so frictionloss stays 0 and ``run``
  applies the same smooth term as a passive force at every integrator stage (mjcb_passive).
  The MJCF lists the coefficients in a comment; a viewer without robotgen simulates
  without them.
- gravity is one vector in MuJoCo: every chain, mechanism and payload must agree on it.
- a formulas leaf without ``mechanism``, a formulas payload, an ATTACH by formulas
  (h, J, G) and contacts whose fingertip coordinates are not one leaf's tip: refused with
  a located message.
- run-time parameters (a payload's mass, say) take their spec values.
- joint limits are not written: robotgen's plant has none either.
- inertias that break the triangle inequality I1 + I2 >= I3 (published ones do: the PUMA
  560's links 1 and 3): MuJoCo refuses them. A link whose revolute joint turns about a
  carries inertia delta (1 - a a^T) for the parent: the kinetic energy it adds,
  delta (|w|^2 - (w . a)^2) / 2 with w = w_parent + qd a, does not depend on qd. So
  ``physical_inertias`` adds the smallest such delta that makes the link physical and takes
  it off the parent (off nothing for a link on the base), tip to base: the same M, C, N.
- point masses: MuJoCo requires every moving body's mass and principal moments above
  1e-15; the compiler's boundmass and boundinertia raise them to MIN_INERTIA (1e-14 kg and
  kg m^2), which changes the Styx fingers' M by about 1e-11 relative.

The writer imports no MuJoCo (robotgen.simulation.mujoco.run does)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from robotgen.documentation import hint
from robotgen.errors import Location, UserError
from robotgen.model.chain import PRISMATIC, KinematicTree, mimic_joints
from robotgen.model.formula import FormulaRobot
from robotgen.model.signature import robot_leaves
from robotgen.model.system import (
    CONTACT_GRASPS,
    FRAME_CHANGE,
    PLANAR_CONTACTS,
    PLANAR_OUTPUT,
    AttachNode,
    DefineNode,
    PlanarBody,
    RobotSystem,
    SpatialBody,
    leaf_of,
    under_controls,
)

FINGERTIP_RADIUS = 0.001  # [m] each fingertip's sphere
# [s] the contacts' solref time constant (critically damped): stiff enough that a 1 N squeeze
# on the Styx box presses the pads in by tens of micrometres, and 20 MuJoCo steps long
CONTACT_TIMECONST = 0.002
CONTACT_SUBSTEPS = 10  # MuJoCo steps per servo period when there are contacts (one without)
MIN_INERTIA = 1e-14  # [kg, kg m^2] the compiler's boundmass and boundinertia
# MuJoCo's soft friction constraint lets a payload held by friction creep (the tripod's 1 kg box
# slid 2.4 mm in 2 s under its weight at |f_t| / (mu f_n) = 0.45); its noslip solver, run after
# the main one, takes that out (7 um)
NOSLIP_ITERATIONS = 20
LINK_RADIUS = 0.004  # [m] capsules drawn along the links (no mass, no collisions)


@dataclass(frozen=True, eq=False)
class LeafMap:
    """One actuated leaf: theta[coordinates] = T qpos[joints] + offset."""

    name: str
    joints: tuple[str, ...]  # MuJoCo joint names, in the chain's order
    coordinates: tuple[str, ...]  # robotgen's coordinate names
    actuators: tuple[str, ...]  # one per coordinate
    theta: slice  # the leaf's entries of robotgen's theta
    T: np.ndarray
    offset: np.ndarray
    coulomb: np.ndarray  # per MuJoCo joint
    smoothing: float
    tip: str  # the site at its tip frame
    tip_body: str
    location: Location  # what a message about this leaf points at


@dataclass(frozen=True, eq=False)
class PayloadMap:
    """A payload node as MJCF: its ATTACH, planar or spatial, its joints (x, y, psi or a free joint) and body."""

    node: str
    attach: str
    planar: bool
    joints: tuple[str, ...]  # x, y, psi (planar) or the free joint
    body: str


@dataclass(frozen=True, eq=False)
class ContactMap:
    """Contact ``index`` of ``attach``: the fingertip of ``leaf`` on its pad of ``payload``."""

    attach: str
    index: int
    leaf: str
    payload: str
    pair: str
    tip_geom: str
    pad_geom: str
    point: np.ndarray  # (3,) the contact point in the payload's frame
    normal: np.ndarray  # (3,) the pad's outward normal in the payload's frame
    friction: float
    planar: bool

    @property
    def name(self) -> str:
        """The contact's name: <attach>.c<k>."""
        return f"{self.attach}.c{self.index + 1}"


@dataclass(frozen=True, eq=False)
class WallMap:
    """The wall: the tip sphere of ``leaf`` against the plane, both geoms by name."""

    leaf: str
    tip_geom: str
    plane_geom: str


@dataclass(frozen=True, eq=False)
class PlantModel:
    """A system as an MJCF plant: the XML, maps of leaves, payloads and contacts, MuJoCo's timestep [s] and substeps."""

    name: str
    xml: str
    leaves: tuple[LeafMap, ...]
    payloads: tuple[PayloadMap, ...]
    contacts: tuple[ContactMap, ...]
    timestep: float  # MuJoCo's step
    substeps: int  # MuJoCo steps per servo period
    gravity: np.ndarray
    hand_payload: str | None = None  # hand laws: the body that takes the payload changes
    wall: WallMap | None = None  # the simulation's wall

    @property
    def nq(self) -> int:
        """The number of leaf coordinates the plant maps."""
        return sum(leaf.T.shape[0] for leaf in self.leaves)


def below_controls(system: RobotSystem, name: str) -> DefineNode | AttachNode:
    """The leaf or ATTACH node below any controllers of ``name``."""
    return under_controls(system.nodes, name)


def _element(world: ET.Element, path: str) -> ET.Element:
    """The element at ``path`` of the model being written (written before it is looked for)."""
    found = world.find(path)
    if found is None:
        raise ValueError(f"the MJCF being written has no {path}")
    return found


def _vec(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def quaternion(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix (Shepperd's method: the largest of the four
    squares is taken first, so no division by a small number)."""
    t = np.trace(R)
    squares = [t, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(squares))
    if k == 0:
        w = np.sqrt(1.0 + t) / 2
        q = [w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)]
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        s = np.sqrt(1.0 + R[i, i] - R[j, j] - R[m, m]) / 2
        q = [0.0] * 4
        q[0] = (R[m, j] - R[j, m]) / (4 * s)
        q[1 + i], q[1 + j], q[1 + m] = s, (R[j, i] + R[i, j]) / (4 * s), (R[m, i] + R[i, m]) / (4 * s)
    quaternion = np.array(q)
    return quaternion if quaternion[0] >= 0 else -quaternion


def _place(element: ET.Element, pose: np.ndarray) -> None:
    """pos and quat of a 4x4 pose (none where it is the identity)."""
    if np.any(pose[:3, 3]):
        element.set("pos", _vec(pose[:3, 3]))
    if not np.array_equal(pose[:3, :3], np.eye(3)):
        element.set("quat", _vec(quaternion(pose[:3, :3])))


def _link(body: ET.Element, offset: np.ndarray) -> None:
    """A massless capsule drawing the link from ``body``'s origin to ``offset`` (none if zero)."""
    if np.any(offset):
        ET.SubElement(
            body,
            "geom",
            type="capsule",
            size=repr(LINK_RADIUS),
            fromto=_vec(np.r_[np.zeros(3), offset]),
            rgba="0.5 0.5 0.6 1",
        )


def _inertial(parent: ET.Element, mass: float, com: np.ndarray, inertia: np.ndarray) -> None:
    """mass, centre of mass and the principal moments of the inertia tensor (about the
    centre of mass) with their axes; a diagonal tensor is written as it is."""
    element = ET.SubElement(parent, "inertial", mass=repr(float(mass)), pos=_vec(com))
    if np.array_equal(inertia, np.diag(np.diag(inertia))):
        element.set("diaginertia", _vec(np.diag(inertia)))
        return
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    element.set("diaginertia", _vec(np.maximum(moments, 0.0)))
    element.set("quat", _vec(quaternion(axes)))


def _physical(inertia: np.ndarray) -> bool:
    """Principal moments non-negative and I1 + I2 >= I3 with a margin over rounding (MuJoCo's
    test); a zero tensor passes (a point mass: the compiler bounds its moments)."""
    moments = np.linalg.eigvalsh(inertia)
    if moments[2] <= MIN_INERTIA:
        return bool(moments[0] >= -MIN_INERTIA)
    return bool(moments[0] >= -1e-12 * moments[2] and moments[0] + moments[1] >= (1 + 1e-9) * moments[2])


def physical_inertias(tree: KinematicTree) -> list[np.ndarray]:
    """Every link's inertia (about its centre of mass, in its joint frame), made physical by
    moving inertia delta (1 - a a^T) about a revolute joint's axis a from the parent to the
    link (delta 1 for a prismatic joint, whose link turns as its parent does): the dynamics
    are unchanged (module docstring). Tip to base, so a parent left unphysical is mended in
    turn; a link on the base takes it from nothing."""
    inertias = [np.array(j.body.inertia, float) for j in tree.joints]
    for i in reversed(range(len(tree.joints))):
        if _physical(inertias[i]):
            continue
        joint = tree.joints[i]
        a = np.asarray(joint.axis, float)
        D = np.eye(3) if joint.type == PRISMATIC else np.eye(3) - np.outer(a, a)
        high = max(float(np.abs(inertias[i]).max()), 1e-12)
        while not _physical(inertias[i] + high * D):
            high *= 2
        low = 0.0
        for _ in range(60):  # bisection to the smallest delta that passes
            mid = (low + high) / 2
            low, high = (low, mid) if _physical(inertias[i] + mid * D) else (mid, high)
        inertias[i] = inertias[i] + high * D
        if joint.parent >= 0:
            R = joint.origin[:3, :3]
            inertias[joint.parent] = inertias[joint.parent] - high * (R @ D @ R.T)
    return inertias


def _chain_bodies(world: ET.Element, leaf: str, tree: KinematicTree) -> tuple[list[str], str]:
    """The tree's bodies below ``world``; (MuJoCo joint names, the body of the tip joint)."""
    bodies: list[ET.Element] = []
    names = []
    inertias = physical_inertias(tree)
    for joint, inertia in zip(tree.joints, inertias):
        parent = world if joint.parent < 0 else bodies[joint.parent]
        name = f"{leaf}/{joint.name}"
        body = ET.SubElement(parent, "body", name=name)
        _place(body, joint.origin)
        attributes = {"name": name, "type": "slide" if joint.type == PRISMATIC else "hinge", "axis": _vec(joint.axis)}
        if joint.armature:
            attributes["armature"] = repr(float(joint.armature))
        if joint.viscous:
            attributes["damping"] = repr(float(joint.viscous))
        ET.SubElement(body, "joint", attributes)
        if not np.array_equal(inertia, joint.body.inertia):
            body.append(
                ET.Comment(
                    " inertia made physical by moving some about the joint axis to or from the "
                    "parent: the same dynamics (robotgen.simulation.mujoco.model) "
                )
            )
        _inertial(body, joint.body.mass, joint.body.com, inertia)
        if parent is not world:
            _link(parent, joint.origin[:3, 3])
        bodies.append(body)
        names.append(name)
    tip = bodies[tree.tip]
    _link(tip, tree.tool[:3, 3])
    site = ET.SubElement(tip, "site", name=f"{leaf}/tip", size=repr(FINGERTIP_RADIUS / 2))
    _place(site, tree.tool)
    return names, f"{leaf}/{tree.joints[tree.tip].name}"


def _leaf_tree(system: RobotSystem, name: str) -> tuple[KinematicTree, np.ndarray, np.ndarray, Location]:
    leaf = system.leaf(name)
    if isinstance(leaf, KinematicTree):
        if leaf.coupling is not None:
            raise UserError(
                system.location_of(name),
                f"the MuJoCo plant couples no joints exactly: chain leaf "
                f"'{name}' has mimic joints ({mimic_joints(leaf)}), which MuJoCo "
                "would hold by a soft equality constraint; simulate it on "
                f"robotgen's plant ({hint('spec-format', 'Mimic joints')})",
            )
        return leaf, np.eye(leaf.nq), np.zeros(leaf.nq), system.location_of(name)
    if isinstance(leaf, FormulaRobot) and leaf.mechanism is not None:
        m = leaf.mechanism
        return m.tree, m.T, m.offset, m.location
    raise UserError(
        system.location_of(name),
        f"the MuJoCo plant builds every leaf from bodies: formulas leaf "
        f"'{name}' needs a mechanism (a chain whose joints give its "
        f"coordinates: {hint('spec-format', 'mechanism')})",
    )


def fingertips(system: RobotSystem, attach: AttachNode) -> list[str]:
    """The leaf whose tip each contact's fingertip coordinates are, in contact order: a leaf
    robot's own coordinates, or each robot's kinematic outputs through a frame change."""
    kind = attach.constraint.kind
    dim = CONTACT_GRASPS[kind].tip_dim
    where = system.location_of(attach.name)
    tips = []
    for r in attach.robots:
        below = below_controls(system, r)
        if isinstance(below, DefineNode):
            blocks = [(below.name, system.leaf(below.name).nq)]
        elif isinstance(below, AttachNode) and below.constraint.kind == FRAME_CHANGE:
            blocks = []
            for r2 in below.robots:
                sub = below_controls(system, r2)
                sub_leaf = leaf_of(sub)
                n = (
                    len(sub_leaf.kinematics or ())
                    if isinstance(sub_leaf, FormulaRobot)
                    else 2
                    if below.constraint.output == PLANAR_OUTPUT
                    else 3
                )
                blocks.append((sub.name, n))
        else:
            raise UserError(
                where,
                f"the MuJoCo plant needs each fingertip of {kind} to be one leaf's tip; robot '{r}' "
                f"is a {below.primitive} node that is not a frame change of leaves",
            )
        for leaf, n in blocks:
            if n != dim:
                raise UserError(
                    where,
                    f"the MuJoCo plant takes leaf '{leaf}''s {n} coordinates as one fingertip; "
                    f"a contact of {kind} has {dim}",
                )
            tips.append(leaf)
    return tips


def _gravity(system: RobotSystem, leaves: list[tuple[str, KinematicTree, Location]], payloads: list[str]) -> np.ndarray:
    """The one gravity vector of the MuJoCo model: every chain's, mechanism's and payload's."""
    given = [(f"leaf '{name}'", np.asarray(tree.gravity, float), where) for name, tree, where in leaves]
    for p in payloads:
        body = system.leaf(p)
        if isinstance(body, PlanarBody):
            g = np.r_[body.gravity, 0.0]
        elif isinstance(body, SpatialBody):
            g = np.asarray(body.gravity, float)
        else:  # (the caller refuses such a payload)
            raise TypeError(f"payload '{p}' is no rigid body")
        given.append((f"payload '{p}'", g, system.location_of(p)))
    first = given[0]
    for what, g, where in given[1:]:
        if not np.allclose(g, first[1], rtol=0, atol=1e-12):
            raise UserError(
                where,
                f"MuJoCo has one gravity: {what} has ({_vec(g)}) m/s^2 but {first[0]} "
                f"({_vec(first[1])}); give them the same (a planar payload's (gx, gy) is "
                "(gx, gy, 0))",
            )
    return first[1]


def plant_model(system: RobotSystem, period: float, hand_frame: np.ndarray | None = None) -> PlantModel:
    """The MJCF of ``system`` stepped at the servo ``period`` (CONTACT_SUBSTEPS MuJoCo steps
    per period when there are contacts). ``hand_frame``: a hand law's hand in its chain's
    last joint frame, where a massless body takes the payload changes. Raises UserError,
    located, for what cannot be mapped."""
    leaves = robot_leaves(system)
    attaches = [n for n in system.walk() if isinstance(n, AttachNode)]
    for a in attaches:
        if a.constraint.kind != FRAME_CHANGE and a.constraint.kind not in CONTACT_GRASPS:
            raise UserError(
                system.location_of(a.name),
                f"the MuJoCo plant has no counterpart of attach '{a.name}''s "
                "formulas constraint (h, J, G): it maps frame changes and "
                "planar or point contacts",
            )
    grasps = [a for a in attaches if a.constraint.kind in CONTACT_GRASPS]
    for a in grasps:
        if a.payload is None:  # (the front end gives every contact grasp a payload)
            raise UserError(system.location_of(a.name), f"the MuJoCo plant needs a payload on '{a.name}'")
        payload = system.leaf(a.payload)
        if not isinstance(payload, (PlanarBody, SpatialBody)):
            raise UserError(
                system.location_of(a.payload),
                f"the MuJoCo plant needs payload '{a.payload}' to be a rigid_body (a formulas payload has no bodies)",
            )
    trees = {name: _leaf_tree(system, name) for name in leaves}
    gravity = _gravity(
        system, [(n, t[0], t[3]) for n, t in trees.items()], [a.payload for a in grasps if a.payload is not None]
    )
    wall = system.simulation.wall if system.simulation is not None and hand_frame is None else None
    substeps = CONTACT_SUBSTEPS if grasps or wall is not None else 1
    root = ET.Element("mujoco", model=system.name)
    root.append(
        ET.Comment(
            f" written by robotgen from {system.source}: the plant of `robotgen simulate "
            f"--plant mujoco`; {hint('spec-format', 'The MuJoCo plant')} says how each part maps "
        )
    )
    ET.SubElement(
        root,
        "compiler",
        angle="radian",
        inertiafromgeom="false",
        boundmass=repr(MIN_INERTIA),
        boundinertia=repr(MIN_INERTIA),
    )
    option = ET.SubElement(
        root, "option", timestep=repr(period / substeps), integrator="RK4", cone="elliptic", gravity=_vec(gravity)
    )
    if grasps:
        option.set("noslip_iterations", str(NOSLIP_ITERATIONS))
    default = ET.SubElement(ET.SubElement(root, "default"), "geom")
    default.set("contype", "0")  # only the contact pairs below touch
    default.set("conaffinity", "0")
    world = ET.SubElement(root, "worldbody")
    tendon = ET.Element("tendon")
    actuator = ET.Element("actuator")
    maps, offset = [], 0
    for name in leaves:
        tree, T, theta0, where = trees[name]
        leaf = system.leaf(name)
        coordinates = tuple(j.name for j in leaf.joints) if isinstance(leaf, KinematicTree) else leaf.coordinates
        coulomb = np.array([j.coulomb for j in tree.joints])
        mechanism = leaf.mechanism if isinstance(leaf, FormulaRobot) else None
        world.append(
            ET.Comment(
                f" leaf '{name}'"
                + (
                    ""
                    if mechanism is None
                    else ": the mechanism of a formulas leaf, "
                    + ", ".join(f"{c} = {e.text}" for c, e in zip(coordinates, mechanism.coordinates))
                )
                + (
                    ". Coulomb friction c tanh(qd / "
                    + repr(tree.coulomb_smoothing)
                    + "), c = "
                    + _vec(coulomb)
                    + ", is applied by robotgen as a passive force"
                    if coulomb.any()
                    else ""
                )
                + " "
            )
        )
        joints, tip_body = _chain_bodies(world, name, tree)
        actuators = []
        for i, c in enumerate(coordinates):
            act = f"{name}/{c}"
            used = np.flatnonzero(T[i])
            if len(used) == 1 and T[i, used[0]] == 1.0:
                ET.SubElement(actuator, "motor", name=act, joint=joints[used[0]], gear="1")
            else:
                fixed = ET.SubElement(tendon, "fixed", name=act)
                for j in used:
                    ET.SubElement(fixed, "joint", joint=joints[j], coef=repr(float(T[i, j])))
                ET.SubElement(actuator, "motor", name=act, tendon=act, gear="1")
            actuators.append(act)
        span = slice(offset, offset + len(coordinates))
        maps.append(
            LeafMap(
                name,
                tuple(joints),
                coordinates,
                tuple(actuators),
                span,
                T,
                theta0,
                coulomb,
                tree.coulomb_smoothing,
                f"{name}/tip",
                tip_body,
                where,
            )
        )
        offset += len(coordinates)
    payloads, contacts = [], []
    contact = ET.Element("contact")
    for a in grasps:
        payload_map = _payload(world, system, a)
        payloads.append(payload_map)
        body = _element(world, f".//body[@name='{payload_map.body}']")
        tips = fingertips(system, a)
        planar = a.constraint.kind == PLANAR_CONTACTS
        for k, (point, tip_leaf) in enumerate(zip(np.asarray(a.constraint.contacts, float), tips)):
            contacts.append(
                _contact(
                    contact,
                    world,
                    body,
                    a,
                    k,
                    np.r_[point, 0.0] if planar else point,
                    tip_leaf,
                    payload_map,
                    planar,
                    system,
                )
            )
    wall_map = _wall(contact, world, system, wall) if wall is not None else None
    hand_payload = None
    if hand_frame is not None:
        tip = _element(world, f".//body[@name='{maps[0].tip_body}']")
        hand_payload = "hand_payload"
        tip.append(ET.Comment(" the hand's payload: robotgen sets its mass and centre of mass at each payload change "))
        held = ET.SubElement(tip, "body", name=hand_payload)
        _place(held, hand_frame)
        ET.SubElement(held, "inertial", mass="0", pos="0 0 0", diaginertia="0 0 0")
    for element in (tendon, actuator, contact):
        if len(element):
            root.append(element)
    ET.indent(root)
    xml = ET.tostring(root, encoding="unicode") + "\n"
    return PlantModel(
        system.name,
        xml,
        tuple(maps),
        tuple(payloads),
        tuple(contacts),
        period / substeps,
        substeps,
        gravity,
        hand_payload,
        wall_map,
    )


def wall_leaf(system: RobotSystem, node: str) -> str:
    """The leaf whose tip the wall's node is: the node itself (below its controllers), or the one
    robot of a frame change. Raises UserError otherwise."""
    below = below_controls(system, node)
    if isinstance(below, DefineNode):
        return below.name
    if isinstance(below, AttachNode) and below.constraint.kind == FRAME_CHANGE and len(below.robots) == 1:
        leaf = below_controls(system, below.robots[0])
        if isinstance(leaf, DefineNode):
            return leaf.name
    where = (
        system.simulation.locations.get("wall", system.location_of(node))
        if system.simulation is not None
        else system.location_of(node)
    )
    raise UserError(
        where,
        f"the MuJoCo plant puts the wall against one leaf's tip: node '{node}' must be a leaf or a "
        "frame change of one leaf (its tip position)",
    )


def _wall(contact: ET.Element, world: ET.Element, system: RobotSystem, wall) -> WallMap:
    """The plane (its face FINGERTIP_RADIUS inside the wall's, so that the sphere on the tip
    touches it when the tip reaches the wall) and the pair of it with that sphere."""
    leaf = wall_leaf(system, wall.node)
    point, normal = (np.r_[np.asarray(v, float), np.zeros(3 - len(v))] for v in (wall.point, wall.normal))
    ET.SubElement(
        world,
        "geom",
        name="wall",
        type="plane",
        size="0 0 1",
        pos=_vec(point - FINGERTIP_RADIUS * normal),
        zaxis=_vec(normal),
        rgba="0.6 0.6 0.6 0.5",
    )
    tip_site = _element(world, f".//site[@name='{leaf}/tip']")
    holder = next(b for b in world.iter("body") if tip_site in list(b))
    ET.SubElement(
        holder,
        "geom",
        name="wall/tip",
        type="sphere",
        size=repr(FINGERTIP_RADIUS),
        pos=tip_site.get("pos", "0 0 0"),
        rgba="0.2 0.4 0.8 1",
    )
    ET.SubElement(
        contact, "pair", name="wall", geom1="wall/tip", geom2="wall", condim="1", solref=f"{CONTACT_TIMECONST!r} 1"
    )
    return WallMap(leaf, "wall/tip", "wall")


def _payload(world: ET.Element, system: RobotSystem, attach: AttachNode) -> PayloadMap:
    name = attach.payload
    if name is None:  # (a contact grasp has a payload)
        raise TypeError(f"attach '{attach.name}' has no payload")
    body = system.leaf(name)
    element = ET.SubElement(world, "body", name=name)
    if isinstance(body, PlanarBody):
        joints = tuple(f"{name}/{c}" for c in body.coordinates)
        for joint, (kind, axis) in zip(joints, (("slide", "1 0 0"), ("slide", "0 1 0"), ("hinge", "0 0 1"))):
            ET.SubElement(element, "joint", name=joint, type=kind, axis=axis)
        ET.SubElement(
            element, "inertial", mass=repr(float(body.mass)), pos="0 0 0", diaginertia=_vec([body.inertia] * 3)
        )
        return PayloadMap(name, attach.name, True, joints, name)
    if not isinstance(body, SpatialBody):  # (build_plant refuses another payload)
        raise TypeError(f"payload '{name}' is no rigid body")
    ET.SubElement(element, "freejoint", name=f"{name}/free")
    _inertial(element, body.mass, np.zeros(3), np.asarray(body.inertia, float))
    return PayloadMap(name, attach.name, False, (f"{name}/free",), name)


def _contact(
    contact: ET.Element,
    world: ET.Element,
    body: ET.Element,
    attach: AttachNode,
    k: int,
    point: np.ndarray,
    leaf: str,
    payload: PayloadMap,
    planar: bool,
    system: RobotSystem,
) -> ContactMap:
    """Contact k: the fingertip sphere on ``leaf``'s tip, the pad on the payload, their pair."""
    distance = float(np.linalg.norm(point))
    if distance <= 2 * FINGERTIP_RADIUS:
        raise UserError(
            system.location_of(attach.name),
            f"the MuJoCo plant faces each pad away from the payload's "
            f"centre: contact point {k + 1} of '{attach.name}' is "
            f"{distance:.3g} m from it, closer than "
            f"{2 * FINGERTIP_RADIUS:g} m",
        )
    normal = point / distance
    half = max(0.5 * distance, 4 * FINGERTIP_RADIUS)  # the pad's half width along the face
    pad = f"{attach.name}/pad{k + 1}"
    centre = point - 2 * FINGERTIP_RADIUS * normal  # face FINGERTIP_RADIUS inside the point, as thick
    ET.SubElement(
        body,
        "geom",
        name=pad,
        type="box",
        size=_vec([half, half, FINGERTIP_RADIUS]),
        pos=_vec(centre),
        zaxis=_vec(normal),
        rgba="0.8 0.6 0.2 0.6",
    )
    tip_site = _element(world, f".//site[@name='{leaf}/tip']")
    holder = next(b for b in world.iter("body") if tip_site in list(b))
    tip = f"{attach.name}/tip{k + 1}"
    ET.SubElement(
        holder,
        "geom",
        name=tip,
        type="sphere",
        size=repr(FINGERTIP_RADIUS),
        pos=tip_site.get("pos", "0 0 0"),
        rgba="0.2 0.4 0.8 1",
    )
    pair = f"{attach.name}/c{k + 1}"
    mu = repr(float(attach.constraint.friction))
    ET.SubElement(
        contact,
        "pair",
        name=pair,
        geom1=tip,
        geom2=pad,
        condim="3",
        friction=f"{mu} {mu} 0 0 0",
        solref=f"{CONTACT_TIMECONST!r} 1",
    )
    return ContactMap(
        attach.name, k, leaf, payload.node, pair, tip, pad, point, normal, float(attach.constraint.friction), planar
    )
