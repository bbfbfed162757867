"""Read a URDF file into a KinematicTree: the chain of movable joints from a base link to a
tip link (``read_urdf``), or every movable joint below a base link (``read_urdf_tree``, e.g.
a humanoid's joints below its pelvis).

Parsed into plain elements with their positions (``urdf_xml``), then checked against the
subset of URDF robotgen understands:
- inside <link>, <joint> and <inertial>, each element is read, accepted unread (URDF's own
  elements without dynamic meaning: visual, collision, ...), skipped with one located note
  per element name (pybullet's <contact>, Gazebo's flags: no rigid-body meaning), or
  refused because misreading it would change the dynamics (``urdf_elements`` lists them);
  so is an unknown joint type, and a non-finite number in an origin, axis, inertial or
  <dynamics>;
- any other element directly under <robot> (<ros2_control>, a vendor's tags) is ignored
  with its children, unchecked, and reported in one note (``UrdfChain.notes``) naming each
  such tag once with the line of its first occurrence;
- "no limit" markers in <limit> (a magnitude of 1e15 or more; pybullet's lower="1"
  upper="-1" and Bullet's default lower="0" upper="-1") read as no limit, with one note per
  marker; any other lower above upper is an error.

Normalisation (into robotgen.model.chain's canonical form):
- fixed joints are folded away: the inertia of every link they carry is merged into the
  body of the nearest movable joint above it (or dropped when it is fixed to the base);
- chain: movable joints that are not on the base -> tip path (a gripper's fingers) are
  locked at q = 0 and treated as fixed; they are listed in ``KinematicTree.locked_joints``.
  Off the path, the joints coupled to a path joint's coordinate move with the chain, as
  branches: a mimic joint following a path joint, and the leader of a mimic joint on the
  path (the coordinate is then the leader's);
- tree: all movable joints below the base are kept, in depth-first order with parent
  indices;
- both: a mimic joint (``urdf_mimic``) stays a joint of the tree and is coupled to the
  coordinate of the joint it follows (``KinematicTree.coupling``, q = multiplier q_leader +
  offset), so the robot has one coordinate fewer per mimic joint; one note names them;
- both: only what is below the base is read, so a floating or planar joint above it (a
  humanoid's world -> pelvis joint) is no error; one below it is;
- URDF <dynamics damping> becomes viscous friction, <dynamics friction> Coulomb friction.

``load_urdf_system`` names the module after <robot name> made an identifier (lower case,
other characters '_') unless a name is given; when that changes the name, a note says so.

Every constant placed into the model (origins, merged inertias, unit axes) is computed with
robotgen.numeric.exact, so the emitted C is the same to the bit on every machine.
"""

from __future__ import annotations

import difflib
import hashlib
import math
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from robotgen.errors import Location, UserError
from robotgen.frontend.input_file import read_input
from robotgen.frontend.urdf_elements import KNOWN_UNREAD, ElementCheck
from robotgen.frontend.urdf_mimic import coupled_note, coupling_of, independent_joints, read_mimics
from robotgen.frontend.urdf_xml import Element, declaration_first, parse_xml
from robotgen.model.chain import PRISMATIC, REVOLUTE, Body, Joint, KinematicTree, Limits, joints_without_inertia
from robotgen.model.expression import MAX_MAGNITUDE
from robotgen.model.names import MAX_LENGTH, name_problem
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.model.transforms import xyz_rpy
from robotgen.numeric import exact

_JOINT_TYPES = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC, "fixed": None}
# Bounds read before anything is built: real robot descriptions are far below both (the
# largest in example-robot-data: 210 kB, 130 links); a file past them is refused, located.
MAX_BYTES = 16_000_000
MAX_LINKS = 1000
_UNSUPPORTED_TYPES = {"floating": "a floating joint", "planar": "a planar joint"}
# "No limit" in <limit>: a magnitude of at least this (-1e16 .. 1e16 in exported files) ...
NO_LIMIT_MAGNITUDE = 1e15
# ... or lower above upper as pybullet's data writes it (1, -1) and Bullet's parser defaults
# it (0, -1); any other lower above upper is an error.
NO_LIMIT_PAIRS = {(1.0, -1.0), (0.0, -1.0)}


class _Reader:
    def __init__(self, path: str, root: Element):
        self.path = path
        self.root = root

    def loc(self, el: Element) -> Location:
        return Location(self.path, el.line, el.col)

    def fail(self, el: Element, message: str) -> UserError:
        return UserError(self.loc(el), message)

    def check_robot(self) -> tuple[list[Element], tuple[str, ...]]:
        """Check every <link> and <joint> (urdf_elements); return the elements directly under
        <robot> that robotgen does not know (e.g. <ros2_control>), which are ignored
        unchecked, and the notes on what was skipped inside links and joints."""
        foreign = []
        check = ElementCheck(self.path)
        for child in self.root.children:
            if child.tag in ("link", "joint"):
                check.check(child)
            elif child.tag not in KNOWN_UNREAD:
                foreign.append(child)
        return foreign, check.notes

    def link(self, joint: Element, tag: str) -> str:
        """The link a joint's <parent> or <child> names."""
        ref = joint.find(tag)
        if ref is None:
            raise self.fail(joint, f"joint '{joint.attrib.get('name')}' needs <{tag} link=...>")
        return self.attr(ref, "link")

    def attr(self, el: Element, name: str, default: str | None = None) -> str:
        if name in el.attrib:
            return el.attrib[name]
        if default is None:
            raise self.fail(el, f"<{el.tag}> needs the attribute '{name}'")
        return default

    def floats(self, el: Element | None, name: str, n: int, default: str, finite: bool = True) -> np.ndarray:
        """``n`` numbers from an attribute; with ``finite`` (geometry and inertia, which go
        into exact arithmetic) inf and nan are errors."""
        text = default if el is None else self.attr(el, name, default)
        where = self.root if el is None else el  # (the defaults pass every check)
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != n:
            raise self.fail(
                where, f"<{where.tag}> attribute '{name}' must hold {n} number{'s' if n > 1 else ''}, got '{text}'"
            )
        if finite and not all(math.isfinite(v) for v in values):
            raise self.fail(where, f"<{where.tag}> attribute '{name}' must hold finite numbers, got '{text}'")
        if finite and any(abs(v) > MAX_MAGNITUDE for v in values):
            raise self.fail(
                where,
                f"<{where.tag}> attribute '{name}' holds a number larger than {MAX_MAGNITUDE:g} in magnitude: '{text}'",
            )
        return np.array(values)

    def number(self, el: Element, name: str, default: str | None = None, finite: bool = True) -> float:
        return float(self.floats(el, name, 1, self.attr(el, name, default), finite)[0])

    def limit_value(self, el: Element, name: str) -> float | None:
        """A <limit> attribute, None when absent or a "no limit" magnitude (NO_LIMIT_MAGNITUDE
        or more, infinities included); NaN is an error."""
        if name not in el.attrib:
            return None
        value = float(self.floats(el, name, 1, el.attrib[name], finite=False)[0])
        if math.isnan(value):
            raise self.fail(el, f"<{el.tag}> attribute '{name}' must hold finite numbers, got '{el.attrib[name]}'")
        return None if abs(value) >= NO_LIMIT_MAGNITUDE else value

    def origin(self, el: Element) -> np.ndarray:
        o = el.find("origin")
        return xyz_rpy(self.floats(o, "xyz", 3, "0 0 0"), self.floats(o, "rpy", 3, "0 0 0"))

    def body(self, link: Element) -> Body:
        """The link's inertia in the link frame; a link without <inertial> is massless."""
        inertial = link.find("inertial")
        if inertial is None:
            return Body.zero()
        mass_el, inertia_el = inertial.find("mass"), inertial.find("inertia")
        if mass_el is None or inertia_el is None:
            raise self.fail(inertial, "<inertial> needs <mass> and <inertia>")
        mass = self.number(mass_el, "value")
        if mass < 0:
            raise self.fail(mass_el, f"negative mass {mass}")
        v = {k: self.number(inertia_el, k) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
        if np.linalg.eigvalsh(I).min() < -1e-12 * max(1.0, np.abs(I).max()):
            raise self.fail(inertia_el, "inertia tensor is not positive semi-definite")
        T = self.origin(inertial)
        R = T[:3, :3]
        return Body(mass, T[:3, 3].copy(), exact.matmul(R, I, R.T))


def merge_bodies(parts: list[tuple[np.ndarray, Body]]) -> Body:
    """One body equal to rigidly joined bodies, each given with the transform from the
    common frame to its own frame (parallel-axis theorem). Exact sums and products
    (robotgen.numeric.exact), rounded once per step: the same bits on every machine."""
    placed = []
    for T, b in parts:
        R = T[:3, :3]
        com = exact.matmul(T, np.append(b.com, 1.0))[:3]  # R c + p, rounded once
        placed.append((b.mass, com, exact.matmul(R, b.inertia, R.T)))
    mass = math.fsum(m for m, _, _ in placed)
    if mass == 0:
        return Body.zero()
    # sum m c / sum m, exact and rounded once (one body keeps its com to the bit)
    total = sum((Fraction(float(m)) for m, _, _ in placed), Fraction(0))
    com = np.array(
        [
            float(sum((Fraction(float(m)) * Fraction(float(c[i])) for m, c, _ in placed), Fraction(0)) / total)
            for i in range(3)
        ]
    )
    terms = []
    for m, c, I in placed:
        d = c - com
        shift = exact.add((exact.dot(d, d), np.eye(3)), (-1.0, exact.outer(d, d)))  # |d|^2 E - d d^T
        terms += [I, (m, shift)]
    return Body(mass, com, exact.add(*terms))


@dataclass(frozen=True, eq=False)
class UrdfChain:
    """A tree read from a URDF, with the located notes and warnings for the user (what was
    ignored or locked); ``robot`` is where <robot> starts and ``robot_name`` its name
    attribute (None if absent), for the module-name note."""

    tree: KinematicTree
    notes: tuple[str, ...]
    robot: Location | None = None
    robot_name: str | None = None


def read_urdf(path: str, tip: str, base: str | None = None, name: str | None = None) -> UrdfChain:
    """The chain of movable joints from ``base`` (default: the root link) to ``tip``, and off
    that path the joints coupled to theirs (a mimic joint following one of them, the leader of
    a mimic joint on the path); other movable joints off the path are locked at q = 0."""
    f = read_urdf_file(path)
    r = f.r
    base, order = _below_base(f, base)
    tip = f.known_link("tip", tip)
    if tip not in order:
        raise UserError(r.loc(f.links[tip]), f"tip link '{tip}' is not below base link '{base}'")
    path_links = [tip]
    while path_links[-1] != base:
        path_links.append(f.parent_of[path_links[-1]])
    path_links.reverse()
    path_joints = [f.joints[l] for l in path_links[1:]]
    actuated = [j for j in path_joints if j.attrib["type"] != "fixed"]
    if not actuated:
        raise UserError(r.loc(f.links[tip]), f"no movable joint between '{base}' and '{tip}'")
    movable = [f.joints[l] for l in order[1:] if f.joints[l].attrib["type"] != "fixed"]
    mimics = read_mimics(r, f.joint_names(), movable, base)
    ends = independent_joints(r, mimics)
    end = {j.attrib["name"]: ends.get(j.attrib["name"], j.attrib["name"]) for j in movable}
    moving = {end[j.attrib["name"]] for j in actuated}
    # with the path, every joint of its coordinates: the other finger of a chain to one finger,
    # as a branch, and the leader off the path of a mimic joint on it
    kept = [j for j in movable if end[j.attrib["name"]] in moving]
    canonical, frames, locked, limit_notes = _normalise(f, base, kept)
    tip_owner, tool = frames[tip]
    coupled = [m for m in mimics.values() if end[m.name] in moving]
    return _chain(f, path, name, kept, canonical, (tip_owner, tool), (base, tip), mimics, coupled, limit_notes, locked)


def read_urdf_tree(path: str, base: str | None = None, tip: str | None = None, name: str | None = None) -> UrdfChain:
    """The whole tree of movable joints below ``base`` (default: the root link), e.g. every
    joint of a humanoid below its pelvis.

    Joints are in depth-first order (children in the order their joints appear in the file),
    so a joint's parent index is always smaller than its own; fixed joints are folded as in
    ``read_urdf``. A mimic joint (typically a gripper's second finger) is kept, coupled to the
    coordinate of the joint it follows (``urdf_mimic``), and named in one note. Links and joints
    not below ``base`` are not read (their inertia does not move with any joint). The
    fk/Jacobian tip is the link ``tip``, or, if none is given, the first leaf link (a link
    without child joints) in that order that some movable joint carries.

    Errors (each naming the element): a floating or planar joint below the base. A humanoid
    whose URDF roots it with a floating joint (world -> pelvis) is read with ``base`` = the
    floating joint's child link, which gives the fixed-base tree below it."""
    f = read_urdf_file(path)
    r = f.r
    base, order = _below_base(f, base)
    if tip is not None:
        tip = f.known_link("tip", tip)
    actuated = [f.joints[l] for l in order[1:] if f.joints[l].attrib["type"] != "fixed"]
    if not actuated:
        raise UserError(r.loc(f.links[base]), f"no movable joint below base link '{base}'")
    mimics = read_mimics(r, f.joint_names(), actuated, base)
    independent_joints(r, mimics)  # no cycle
    canonical, frames, locked, limit_notes = _normalise(f, base, actuated)
    assert not locked
    if tip is None:
        leaves = [l for l in order if not f.children_of.get(l) and frames[l][0] >= 0]
        tip = leaves[0]  # a movable joint's child link is carried by it, so some leaf is
    elif tip not in frames:
        raise UserError(r.loc(f.links[tip]), f"tip link '{tip}' is not below base link '{base}'")
    tip_owner, tool = frames[tip]
    if tip_owner < 0:
        raise UserError(r.loc(f.links[tip]), f"no movable joint between '{base}' and '{tip}'")
    coupled = list(mimics.values())
    return _chain(f, path, name, actuated, canonical, (tip_owner, tool), (base, tip), mimics, coupled, limit_notes)


def _chain(
    f: UrdfFile,
    path: str,
    name: str | None,
    joints: list[Element],
    canonical: list[Joint],
    tip: tuple[int, np.ndarray],
    links: tuple[str, str],
    mimics: dict,
    coupled: list,
    limit_notes: tuple[str, ...],
    locked: list[str] | tuple[str, ...] = (),
) -> UrdfChain:
    """The tree read (``joints`` as URDF elements, ``canonical`` as robotgen's joints), its tip
    (owning joint, tool transform), base and tip links, and every note on reading it."""
    tree = KinematicTree(
        name=name or f.root.attrib.get("name", Path(path).stem),
        joints=tuple(canonical),
        tip=tip[0],
        tool=tip[1],
        gravity=np.array([0.0, 0.0, -9.81]),
        base_link=links[0],
        tip_link=links[1],
        locked_joints=tuple(locked),
        coupling=coupling_of([j.attrib["name"] for j in joints], mimics),
    )
    notes = (
        f.notes
        + coupled_note(f.r, coupled)
        + limit_notes
        + _foreign_dynamics_attributes(f.r, joints)
        + _massless(f.r, joints, tree)
    )
    return UrdfChain(tree, notes, f.r.loc(f.root), f.root.attrib.get("name"))


@dataclass(frozen=True, eq=False)
class UrdfFile:
    """The links and joints of one URDF file, checked (urdf_elements) and known to form one
    tree; ``notes`` on what was skipped or read leniently while reading it."""

    r: _Reader
    links: dict[str, Element]  # by name, in file order
    joints: dict[str, Element]  # by child link
    parent_of: dict[str, str]  # parent link by child link
    children_of: dict[str, list[str]]  # child links in the order of their joints in the file
    root_link: str
    notes: tuple[str, ...]

    @property
    def root(self) -> Element:
        """The file's <robot> element."""
        return self.r.root

    def joint_names(self) -> dict[str, Element]:
        """Every joint by its name."""
        return {j.attrib["name"]: j for j in self.joints.values()}

    def known_link(self, label: str, link: str) -> str:
        """``link``, which must be a link of the file; the nearest names are suggested if not."""
        if link in self.links:
            return link
        near = difflib.get_close_matches(link, self.links, n=3, cutoff=0.6)
        hint = f"; nearest: {', '.join(repr(n) for n in near)}" if near else ""
        raise UserError(
            self.r.loc(self.root),
            f"{label} link '{link}' is not in the URDF{hint} (robotgen info {Path(self.r.path).name} lists its links)",
        )


def read_urdf_file(path: str) -> UrdfFile:
    """Every link and joint of the file at ``path``: duplicate names, unknown links, a link
    with two parent joints, several roots and cycles are errors, located. Floating and
    planar joints are accepted here; the readers refuse them below their base."""
    data, declaration_notes = declaration_first(path, read_input(path, MAX_BYTES, "URDF file"))
    root = parse_xml(path, data)
    r = _Reader(path, root)
    foreign, skipped_notes = r.check_robot()
    links = {}
    for el in root.children:
        if el.tag == "link":
            lname = r.attr(el, "name")
            if lname in links:
                raise r.fail(el, f"duplicate link '{lname}'")
            links[lname] = el
            if len(links) > MAX_LINKS:
                raise r.fail(el, f"more than {MAX_LINKS} links; robotgen reads robots up to that size")
    if not links:
        raise r.fail(root, "the URDF has no <link> elements")
    joints: dict[str, Element] = {}  # child link -> joint element
    joint_names: set[str] = set()
    for el in root.children:
        if el.tag != "joint":
            continue
        jname = r.attr(el, "name")
        if jname in joint_names:
            raise r.fail(el, f"duplicate joint '{jname}'")
        joint_names.add(jname)
        jtype = r.attr(el, "type")
        if jtype not in _JOINT_TYPES and jtype not in _UNSUPPORTED_TYPES:
            raise r.fail(el, f"joint '{el.attrib.get('name')}' has unknown type '{jtype}'")
        for tag in ("parent", "child"):
            ref = el.find(tag)
            if ref is None:
                raise r.fail(el, f"joint '{el.attrib.get('name')}' needs <{tag} link=...>")
            if r.attr(ref, "link") not in links:
                raise r.fail(ref, f"joint '{el.attrib.get('name')}' names unknown link '{ref.attrib['link']}'")
        child = r.link(el, "child")
        if child in joints:
            raise r.fail(
                el,
                f"link '{child}' has two parent joints ('{joints[child].attrib.get('name')}' "
                f"and '{el.attrib.get('name')}'): closed loops are not supported",
            )
        joints[child] = el
    parent_of = {c: r.link(j, "parent") for c, j in joints.items()}
    roots = [l for l in links if l not in joints]
    if len(roots) != 1:
        raise r.fail(root, f"the links must form one tree; found roots {sorted(roots)}")
    children_of = _children_of(parent_of)
    reachable = _depth_first(roots[0], children_of)
    if len(reachable) < len(links):  # one root, one parent per link: the rest form a cycle
        seen = set(reachable)
        stray = next(l for l in links if l not in seen)
        raise r.fail(joints[stray], "the joints form a cycle")
    notes = declaration_notes + _foreign_elements(r, foreign) + skipped_notes
    return UrdfFile(r, links, joints, parent_of, children_of, roots[0], notes)


def _below_base(f: UrdfFile, base: str | None) -> tuple[str, list[str]]:
    """The base link (default: the root link) and the links below it, base first, depth
    first; a floating or planar joint among them is an error. One at the root, read without
    a base, is an error that names the base to choose."""
    r = f.r
    if base is None:
        base = f.root_link
        at_root = [f.joints[c] for c in f.children_of.get(base, []) if f.joints[c].attrib["type"] == "floating"]
        if at_root:
            j = at_root[0]
            child = r.link(j, "child")
            raise r.fail(
                j,
                f"joint '{j.attrib.get('name')}' is a floating joint at the root, which robotgen "
                f"does not support; read the robot below it with base='{child}' (--base {child})",
            )
    base = f.known_link("base", base)
    order = _depth_first(base, f.children_of)
    for link in order[1:]:
        j = f.joints[link]
        jtype = j.attrib["type"]
        if jtype in _UNSUPPORTED_TYPES:
            raise r.fail(
                j,
                f"joint '{j.attrib.get('name')}' is {_UNSUPPORTED_TYPES[jtype]}, which robotgen does "
                f"not support below the base ('{base}'); a base at or below its child link "
                f"'{link}' leaves it out",
            )
    return base, order


def _depth_first(start: str, children_of: dict[str, list[str]]) -> list[str]:
    """Links below ``start`` (inclusive) in depth-first pre-order, children in file order."""
    order, stack = [], [start]
    while stack:
        link = stack.pop()
        order.append(link)
        stack.extend(reversed(children_of.get(link, [])))
    return order


def _children_of(parent_of: dict[str, str]) -> dict[str, list[str]]:
    """Child links of each link, in the order of their joints in the file."""
    children_of: dict[str, list[str]] = {}
    for c, p in parent_of.items():
        children_of.setdefault(p, []).append(c)
    return children_of


def _normalise(f: UrdfFile, base: str, actuated: list[Element]) -> tuple[list[Joint], dict, list[str], tuple[str, ...]]:
    """Canonical joints for the movable joints ``actuated`` (topologically ordered), the
    frame of every link below ``base`` as (owner index or -1 for the base, T owner->link),
    the movable joints below base not in ``actuated`` (locked at q = 0), and the notes on
    "no limit" markers read."""
    r, joints = f.r, f.joints
    actuated_index = {id(j): k for k, j in enumerate(actuated)}
    frames: dict[str, tuple[int, np.ndarray]] = {base: (-1, np.eye(4))}
    locked: list[str] = []
    order = [base]
    for link in order:
        for child in f.children_of.get(link, []):
            j = joints[child]
            owner, T = frames[link]
            k = actuated_index.get(id(j))
            if k is not None:
                frames[child] = (k, np.eye(4))
            else:
                if j.attrib["type"] != "fixed":
                    locked.append(j.attrib.get("name", child))
                frames[child] = (owner, exact.matmul(T, r.origin(j)))  # a locked joint sits at q = 0
            order.append(child)

    parts: list[list[tuple[np.ndarray, Body]]] = [[] for _ in actuated]
    for link in order:
        owner, T = frames[link]
        if owner >= 0:
            parts[owner].append((T, r.body(f.links[link])))

    canonical = []
    markers = _NoLimitMarkers()
    for k, j in enumerate(actuated):
        parent_link = r.link(j, "parent")
        owner, T_parent = frames[parent_link]
        assert owner < k, "joints must be in topological order"
        axis_element = j.find("axis")
        axis = r.floats(axis_element, "xyz", 3, "1 0 0")
        largest = float(np.abs(axis).max())
        if largest == 0:  # (not the default axis)
            raise r.fail(j if axis_element is None else axis_element, f"joint '{j.attrib.get('name')}' has a zero axis")
        # scale by a power of two (exact) so that |axis|^2 neither overflows nor underflows
        axis = np.array([math.ldexp(float(a), -math.frexp(largest)[1]) for a in axis])
        dyn = j.find("dynamics")
        damping = r.number(dyn, "damping", "0") if dyn is not None else 0.0
        friction = r.number(dyn, "friction", "0") if dyn is not None else 0.0
        if dyn is not None and (damping < 0 or friction < 0):
            raise r.fail(dyn, f"joint '{j.attrib.get('name')}': <dynamics> damping and friction must be >= 0")
        joint_type = _JOINT_TYPES[j.attrib["type"]]
        assert joint_type is not None, "fixed joints are merged, not actuated"
        canonical.append(
            Joint(
                name=r.attr(j, "name"),
                type=joint_type,
                parent=owner,
                origin=exact.matmul(T_parent, r.origin(j)),
                axis=exact.unit(axis),
                body=merge_bodies(parts[k]),
                viscous=damping,
                coulomb=friction,
                damping=damping,
                limits=_limits(r, j, markers),
            )
        )
    return canonical, frames, locked, markers.notes(r)


@dataclass
class _NoLimitMarkers:
    """The joints whose <limit> used a "no limit" marker: (joint, limit element, attributes)."""

    large: list[tuple[Element, Element, list[str]]] = field(default_factory=list)
    inverted: list[tuple[Element, Element, list[str]]] = field(default_factory=list)

    def notes(self, r: _Reader) -> tuple[str, ...]:
        out = []
        for found, marker in (
            (self.large, "a magnitude of 1e15 or more"),
            (self.inverted, 'lower above upper as pybullet writes it (lower="1" upper="-1" or lower="0" upper="-1")'),
        ):
            if found:
                listed = ", ".join(f"'{j.attrib.get('name')}' ({' and '.join(names)})" for j, _, names in found)
                out.append(f"{r.loc(found[0][1])}: note: read as no limit, marked by {marker}: {listed}")
        return tuple(out)


def _limits(r: _Reader, j: Element, markers: _NoLimitMarkers) -> Limits:
    """A movable joint's <limit>, its "no limit" markers read as None (and recorded)."""
    limit = j.find("limit")
    if limit is None:
        return Limits()
    name = j.attrib.get("name")
    continuous = j.attrib["type"] == "continuous"  # its lower and upper are not read (URDF)
    keys = ("velocity", "effort") if continuous else ("lower", "upper", "velocity", "effort")
    values = {key: r.limit_value(limit, key) for key in keys}
    large = [key for key in keys if key in limit.attrib and values[key] is None]
    if large:
        markers.large.append((j, limit, large))
    if continuous:
        values["lower"] = values["upper"] = None
    else:  # URDF's defaults: 0
        for key in ("lower", "upper"):
            values[key] = 0.0 if key not in limit.attrib else values[key]
        lower, upper = values["lower"], values["upper"]
        if lower is not None and upper is not None and lower > upper:
            if (lower, upper) not in NO_LIMIT_PAIRS:
                raise r.fail(
                    limit,
                    f"joint '{name}': <limit> lower {lower:g} is above upper {upper:g} (the "
                    '"no limit" markers robotgen reads are a magnitude of 1e15 or more and '
                    'pybullet\'s lower="1" upper="-1")',
                )
            markers.inverted.append((j, limit, ["lower", "upper"]))
            values["lower"] = values["upper"] = None
    for key in ("velocity", "effort"):
        if (values[key] or 0.0) < 0:
            raise r.fail(limit, f"joint '{name}': <limit> {key} must be >= 0")
    return Limits(**values)


def _massless(r: _Reader, actuated: list[Element], tree: KinematicTree) -> tuple[str, ...]:
    """A warning at each joint that moves no mass or inertia: M is singular there."""
    return tuple(
        f"{r.loc(actuated[i])}: warning: joint '{tree.joints[i].name}' moves no mass or inertia "
        "(massless links after it): M is singular and forward dynamics returns no finite answer"
        for i in joints_without_inertia(tree)
    )


def _foreign_elements(r: _Reader, foreign: list[Element]) -> tuple[str, ...]:
    """One note for the unknown elements directly under <robot>, at the first of them,
    naming each tag once with the line where it first occurs."""
    if not foreign:
        return ()
    first: dict[str, Element] = {}
    for el in foreign:
        first.setdefault(el.tag, el)
    listed = ", ".join(f"<{tag}> (line {el.line})" for tag, el in first.items())
    n = len(foreign)
    return (
        f"{r.loc(foreign[0])}: note: ignored {n} element{'s' if n != 1 else ''} robotgen does not use "
        f"under <robot>: {listed}",
    )


def _foreign_dynamics_attributes(r: _Reader, joints: list[Element]) -> tuple[str, ...]:
    """One warning for the <dynamics> attributes outside URDF (e.g. a simulator's), at the
    first joint carrying them."""
    first: Element | None = None
    names: set[str] = set()
    for j in joints:
        d = j.find("dynamics")
        extra = set(d.attrib) - {"damping", "friction"} if d is not None else set()
        if extra and first is None:
            first = d
        names |= extra
    if first is None:
        return ()
    listed = ", ".join(f"'{a}'" for a in sorted(names))
    return (f"{r.loc(first)}: warning: <dynamics> attributes {listed} are not URDF; ignored",)


def load_urdf_system(path: str, tip: str, base: str | None = None, name: str | None = None) -> RobotSystem:
    """A URDF file's chain from its base (or ``base``) to the link ``tip`` as a one-leaf RobotSystem."""
    return _single_leaf_system(path, read_urdf(path, tip, base, name), name is not None)


def load_urdf_tree_system(
    path: str, base: str | None = None, tip: str | None = None, name: str | None = None
) -> RobotSystem:
    """A single-leaf system of the whole tree below ``base`` (``read_urdf_tree``)."""
    return _single_leaf_system(path, read_urdf_tree(path, base, tip, name), name is not None)


def _single_leaf_system(path: str, chain: UrdfChain, named: bool) -> RobotSystem:
    """The system of one URDF leaf; its module is named ``chain.tree.name`` made an
    identifier. Without an explicit name (``named``), a module name that differs from the
    robot's name gets a note."""
    module_name = module_identifier(chain.tree.name)
    notes = chain.notes
    if not named and module_name != chain.tree.name:
        source = (
            f'<robot name="{chain.robot_name}">'
            if chain.robot_name is not None
            else f"the file name '{Path(path).name}'"
        )
        notes += (
            f"{chain.robot or Location(path, 1, 1)}: note: module name '{module_name}' (from {source}); "
            "pass --name to choose another",
        )
    node = DefineNode(module_name, chain.tree)
    sha = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return RobotSystem(module_name, path, sha, {module_name: node}, module_name, warnings=notes)


def module_identifier(name: str) -> str:
    """A module name from a robot's name: ASCII letters, digits and _, and _robot appended
    where the name would be a keyword or hide a standard name (robotgen.model.names)."""
    out = "".join(c if c.isascii() and (c.isalnum() or c == "_") else "_" for c in name.lower())[: MAX_LENGTH - 6]
    out = out if out and not out[0].isdigit() else "_" + out
    return out + "_robot" if name_problem(out) else out
