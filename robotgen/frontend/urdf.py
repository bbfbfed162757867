"""Read a URDF file into a KinematicTree: the chain of movable joints from a base link to a
tip link (``read_urdf``), or every movable joint below a base link (``read_urdf_tree``, e.g.
a humanoid's joints below its pelvis).

Parsed with the standard library's expat (to keep line numbers) into plain elements, then
checked against the subset of URDF robotgen understands:
- inside <link>, <joint> and <inertial>, an element outside that subset could change the
  dynamics, so it is an error naming the element, never skipped silently; so is an unknown
  joint type, and a non-finite number in an origin, axis, inertial or <dynamics>;
- known URDF elements without dynamic meaning (visual, collision, material, transmission,
  gazebo, calibration, safety_controller, sensor) are accepted and not used;
- any other element directly under <robot> (<ros2_control>, a vendor's tags) is ignored
  with its children, unchecked, and reported in one note (``UrdfChain.notes``) naming each
  such tag once with the line of its first occurrence.

Normalisation (into robotgen.model.chain's canonical form):
- fixed joints are folded away: the inertia of every link they carry is merged into the
  body of the nearest movable joint above it (or dropped when it is fixed to the base);
- chain: movable joints that are not on the base -> tip path (a gripper's fingers, mimic
  joints among them) are locked at q = 0 and treated as fixed; they are listed in
  ``KinematicTree.locked_joints``. A mimic joint on the path is an error;
- tree: all movable joints below the base are kept, in depth-first order with parent
  indices, except mimic joints (robotgen has no coupled coordinates): those are locked at
  q = 0 like a chain's off-path joints, listed in ``KinematicTree.locked_joints`` and
  named in one note;
- URDF <dynamics damping> becomes viscous friction, <dynamics friction> Coulomb friction.

``load_urdf_system`` names the module after <robot name> made an identifier (lower case,
other characters '_') unless a name is given; when that changes the name, a note says so.

Every constant placed into the model (origins, merged inertias, unit axes) is computed with
robotgen.numeric.exact, so the emitted C is the same to the bit on every machine.
"""
from __future__ import annotations

import hashlib
import math
import xml.parsers.expat
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from robotgen.errors import Location, UserError
from robotgen.frontend.input_file import read_input
from robotgen.model.chain import PRISMATIC, REVOLUTE, Body, Joint, KinematicTree, Limits, joints_without_inertia
from robotgen.model.expression import MAX_MAGNITUDE
from robotgen.model.names import MAX_LENGTH, name_problem
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.model.transforms import xyz_rpy
from robotgen.numeric import exact

# Known URDF elements without dynamic meaning: accepted silently, their content not checked.
_IGNORED = {"visual", "collision", "material", "transmission", "gazebo", "calibration",
            "safety_controller", "sensor"}
# What robotgen reads inside the elements that carry dynamics; anything else there is an
# error. (Under <robot>, elements other than link, joint and _IGNORED are only noted.)
_CHILDREN = {
    "link": {"inertial"} | _IGNORED,
    "inertial": {"origin", "mass", "inertia"},
    "joint": {"origin", "parent", "child", "axis", "limit", "dynamics", "mimic"} | _IGNORED,
}
_JOINT_TYPES = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC, "fixed": None}
# Bounds read before anything is built: real robot descriptions are far below both (the
# largest in example-robot-data: 210 kB, 130 links); a file past them is refused, located.
MAX_BYTES = 16_000_000
MAX_LINKS = 1000
_UNSUPPORTED_TYPES = {"floating": "a floating joint", "planar": "a planar joint"}


@dataclass
class Element:
    tag: str
    attrib: dict[str, str]
    line: int
    col: int
    children: list[Element] = field(default_factory=list)

    def find(self, tag: str) -> Element | None:
        return next((c for c in self.children if c.tag == tag), None)


def _parse_xml(path: str, data: bytes) -> Element:
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Element] = []
    root: list[Element] = []

    def start(tag, attrib):
        el = Element(tag, dict(attrib), parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        (stack[-1].children if stack else root).append(el)
        stack.append(el)

    def entity(name, *_):
        # no URDF needs one, and expanding them is how a small file becomes gigabytes (the
        # expat in use may predate its amplification limit)
        raise UserError(Location(path, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1),
                        f"the URDF declares an XML entity ('{name}'); robotgen reads URDFs without entities")

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    parser.EntityDeclHandler = entity
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as e:
        raise UserError(Location(path, e.lineno, e.offset + 1),
                        f"not well-formed XML: {xml.parsers.expat.ErrorString(e.code)}") from None
    except LookupError as e:  # the XML declaration names an encoding Python does not know
        first = data.split(b"\n", 1)[0]
        col = first.find(b"encoding") + 1 if b"encoding" in first else 1
        raise UserError(Location(path, 1, col), f"the XML declaration names an encoding Python does not know ({e}); "
                                                "save the URDF as UTF-8") from None
    if not root or root[0].tag != "robot":
        raise UserError(Location(path, 1, 1), "a URDF file must have a <robot> root element")
    return root[0]


class _Reader:
    def __init__(self, path: str, root: Element):
        self.path = path
        self.root = root

    def loc(self, el: Element) -> Location:
        return Location(self.path, el.line, el.col)

    def fail(self, el: Element, message: str) -> UserError:
        return UserError(self.loc(el), message)

    def check_robot(self) -> list[Element]:
        """Check every <link> and <joint>; return the elements directly under <robot> that
        robotgen does not know (e.g. <ros2_control>), which are ignored unchecked."""
        foreign = []
        for child in self.root.children:
            if child.tag in ("link", "joint"):
                self.check_children(child)
            elif child.tag not in _IGNORED:
                foreign.append(child)
        return foreign

    def check_children(self, el: Element) -> None:
        allowed = _CHILDREN.get(el.tag)
        if allowed is None:
            return
        for child in el.children:
            if child.tag not in allowed:
                raise self.fail(child, f"<{child.tag}> is not supported inside <{el.tag}>")
            if child.tag not in _IGNORED:
                self.check_children(child)

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
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != n:
            raise self.fail(el, f"<{el.tag}> attribute '{name}' must hold {n} numbers, got '{text}'")
        if finite and not all(math.isfinite(v) for v in values):
            raise self.fail(el, f"<{el.tag}> attribute '{name}' must hold finite numbers, got '{text}'")
        if finite and any(abs(v) > MAX_MAGNITUDE for v in values):
            raise self.fail(el, f"<{el.tag}> attribute '{name}' holds a number larger than {MAX_MAGNITUDE:g} "
                                f"in magnitude: '{text}'")
        return np.array(values)

    def number(self, el: Element, name: str, default: str | None = None, finite: bool = True) -> float:
        return float(self.floats(el, name, 1, self.attr(el, name, default), finite)[0])

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
        I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                      [v["ixz"], v["iyz"], v["izz"]]])
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
    com = np.array([float(sum((Fraction(float(m)) * Fraction(float(c[i])) for m, c, _ in placed),
                              Fraction(0)) / total) for i in range(3)])
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
    """The chain of movable joints from ``base`` (default: the root link) to ``tip``; movable
    joints off that path (mimic joints among them) are locked at q = 0. A mimic joint on the
    path is an error (its message suggests a tip above it, or the tree reader)."""
    r, links, joints, parent_of, _, foreign = _read_links_and_joints(path, floating_ok=False)
    root = r.root
    root_link = _single_root(r, links, joints)
    base = base or root_link
    for label, link in (("base", base), ("tip", tip)):
        if link not in links:
            raise UserError(Location(path, root.line, root.col), f"{label} link '{link}' is not in the URDF")
    path_links = [tip]
    while path_links[-1] != base:
        up = parent_of.get(path_links[-1])
        if up is None:
            raise UserError(r.loc(links[tip]), f"tip link '{tip}' is not below base link '{base}'")
        if up in path_links:
            raise r.fail(joints[path_links[-1]], "the joints form a cycle")
        path_links.append(up)
    path_links.reverse()
    path_joints = [joints[l] for l in path_links[1:]]
    actuated = [j for j in path_joints if j.attrib["type"] != "fixed"]
    if not actuated:
        raise UserError(r.loc(links[tip]), f"no movable joint between '{base}' and '{tip}'")
    _reject_mimic_on_chain(r, actuated)
    canonical, frames, locked = _normalise(r, links, joints, parent_of, base, actuated)
    tip_owner, tool = frames[tip]
    robot_name = name or root.attrib.get("name", Path(path).stem)
    tree = KinematicTree(
        name=robot_name, joints=tuple(canonical), tip=tip_owner, tool=tool,
        gravity=np.array([0.0, 0.0, -9.81]), base_link=base, tip_link=tip, locked_joints=tuple(locked),
    )
    notes = _foreign_elements(r, foreign) + _foreign_dynamics_attributes(r, actuated)
    notes += tuple(f"{r.loc(actuated[i])}: warning: joint '{tree.joints[i].name}' moves no mass or inertia "
                   "(massless links after it): M is singular and forward dynamics returns no finite answer"
                   for i in joints_without_inertia(tree))
    return UrdfChain(tree, notes, r.loc(root), root.attrib.get("name"))


def read_urdf_tree(path: str, base: str | None = None, tip: str | None = None,
                   name: str | None = None) -> UrdfChain:
    """The whole tree of movable joints below ``base`` (default: the root link), e.g. every
    joint of a humanoid below its pelvis.

    Joints are in depth-first order (children in the order their joints appear in the file),
    so a joint's parent index is always smaller than its own; fixed joints are folded as in
    ``read_urdf``. A mimic joint (typically a gripper's second finger) is locked at q = 0,
    since robotgen has no coupled coordinates: folded like a fixed joint, listed in
    ``locked_joints`` and named in one note; joints below it stay movable. Links and joints
    not below ``base`` are not read (their inertia does not move with any joint). The
    fk/Jacobian tip is the link ``tip``, or, if none is given, the first leaf link (a link
    without child joints) in that order that some movable joint carries.

    Errors (each naming the element): a floating or planar joint below the base. A humanoid
    whose URDF roots it with a floating joint (world -> pelvis) is read with ``base`` = the
    floating joint's child link, which gives the fixed-base tree below it."""
    r, links, joints, parent_of, floating, foreign = _read_links_and_joints(path, floating_ok=True)
    root = r.root
    root_link = _single_root(r, links, joints)
    children_of = _children_of(parent_of)
    reachable = _depth_first(root_link, children_of)
    if len(reachable) < len(links):  # one root, one parent per link: the rest form a cycle
        seen = set(reachable)
        stray = next(l for l in links if l not in seen)
        raise r.fail(joints[stray], "the joints form a cycle")
    if base is None:
        base = root_link
        at_root = [j for j in floating if j.find("parent").attrib["link"] == base]
        if at_root:
            j = at_root[0]
            raise r.fail(j, f"joint '{j.attrib.get('name')}' is a floating joint at the root, which robotgen "
                            f"does not support; read the tree below it with base='{j.find('child').attrib['link']}'")
    for label, link in (("base", base), ("tip", tip)):
        if link is not None and link not in links:
            raise UserError(Location(path, root.line, root.col), f"{label} link '{link}' is not in the URDF")
    order = _depth_first(base, children_of)  # links below base, base first
    for link in order[1:]:
        j = joints[link]
        jtype = j.attrib["type"]
        if jtype in _UNSUPPORTED_TYPES:
            raise r.fail(j, f"joint '{j.attrib.get('name')}' is {_UNSUPPORTED_TYPES[jtype]}, "
                            "which robotgen does not support")
    movable = [joints[l] for l in order[1:] if joints[l].attrib["type"] != "fixed"]
    mimics = [j for j in movable if j.find("mimic") is not None]
    actuated = [j for j in movable if j.find("mimic") is None]
    if not actuated:
        raise UserError(r.loc(links[base]), f"no movable joint below base link '{base}'")
    canonical, frames, locked = _normalise(r, links, joints, parent_of, base, actuated)
    assert sorted(locked) == sorted(j.attrib.get("name", j.find("child").attrib["link"]) for j in mimics)
    if tip is None:
        leaves = [l for l in order if not children_of.get(l) and frames[l][0] >= 0]
        tip = leaves[0]  # a movable joint's child link is carried by it, so some leaf is
    elif tip not in frames:
        raise UserError(r.loc(links[tip]), f"tip link '{tip}' is not below base link '{base}'")
    tip_owner, tool = frames[tip]
    if tip_owner < 0:
        raise UserError(r.loc(links[tip]), f"no movable joint between '{base}' and '{tip}'")
    robot_name = name or root.attrib.get("name", Path(path).stem)
    tree = KinematicTree(
        name=robot_name, joints=tuple(canonical), tip=tip_owner, tool=tool,
        gravity=np.array([0.0, 0.0, -9.81]), base_link=base, tip_link=tip, locked_joints=tuple(locked),
    )
    notes = (_foreign_elements(r, foreign) + _locked_mimics(r, mimics)
             + _foreign_dynamics_attributes(r, actuated))
    return UrdfChain(tree, notes, r.loc(root), root.attrib.get("name"))


def _read_links_and_joints(path: str, floating_ok: bool):
    """(reader, links by name, joint element by child link, parent link by child link,
    floating joints, unknown elements directly under <robot>). A floating joint is an error
    unless ``floating_ok`` (then it is returned, for the caller to accept only above its
    base)."""
    root = _parse_xml(path, read_input(path, MAX_BYTES, "URDF file"))
    r = _Reader(path, root)
    foreign = r.check_robot()
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
    joints = {}  # child link -> joint element
    floating = []
    joint_names: set[str] = set()
    for el in root.children:
        if el.tag != "joint":
            continue
        jname = r.attr(el, "name")
        if jname in joint_names:
            raise r.fail(el, f"duplicate joint '{jname}'")
        joint_names.add(jname)
        jtype = r.attr(el, "type")
        if jtype == "floating" and floating_ok:
            floating.append(el)
        elif jtype in _UNSUPPORTED_TYPES and not floating_ok:
            raise r.fail(el, f"joint '{el.attrib.get('name')}' is {_UNSUPPORTED_TYPES[jtype]}, "
                             "which robotgen does not support")
        elif jtype not in _JOINT_TYPES and jtype not in _UNSUPPORTED_TYPES:
            raise r.fail(el, f"joint '{el.attrib.get('name')}' has unknown type '{jtype}'")
        for tag in ("parent", "child"):
            ref = el.find(tag)
            if ref is None:
                raise r.fail(el, f"joint '{el.attrib.get('name')}' needs <{tag} link=...>")
            if r.attr(ref, "link") not in links:
                raise r.fail(ref, f"joint '{el.attrib.get('name')}' names unknown link '{ref.attrib['link']}'")
        child = el.find("child").attrib["link"]
        if child in joints:
            raise r.fail(el, f"link '{child}' has two parent joints ('{joints[child].attrib.get('name')}' "
                             f"and '{el.attrib.get('name')}'): closed loops are not supported")
        joints[child] = el
    parent_of = {c: j.find("parent").attrib["link"] for c, j in joints.items()}
    return r, links, joints, parent_of, floating, foreign


def _reject_mimic_on_chain(r: _Reader, actuated: list[Element]) -> None:
    for j in actuated:
        mimic = j.find("mimic")
        if mimic is not None:
            raise r.fail(mimic, f"joint '{j.attrib.get('name')}' is a mimic joint (it follows "
                                f"'{mimic.attrib.get('joint', '?')}'), which robotgen does not support on the "
                                f"chain: choose a tip at or above link '{j.find('parent').attrib['link']}' "
                                "(off the chain it is locked at q = 0), or read the whole tree (--tree), "
                                "where mimic joints are locked at q = 0")


def _single_root(r: _Reader, links: dict, joints: dict) -> str:
    roots = [l for l in links if l not in joints]
    if len(roots) != 1:
        raise r.fail(r.root, f"the links must form one tree; found roots {sorted(roots)}")
    return roots[0]


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


def _normalise(r: _Reader, links: dict, joints: dict, parent_of: dict, base: str,
               actuated: list[Element]) -> tuple[list[Joint], dict, list[str]]:
    """Canonical joints for the movable joints ``actuated`` (topologically ordered), the
    frame of every link below ``base`` as (owner index or -1 for the base, T owner->link),
    and the movable joints below base not in ``actuated`` (locked at q = 0)."""
    children_of = _children_of(parent_of)
    actuated_index = {id(j): k for k, j in enumerate(actuated)}
    frames: dict[str, tuple[int, np.ndarray]] = {base: (-1, np.eye(4))}
    locked: list[str] = []
    order = [base]
    for link in order:
        for child in children_of.get(link, []):
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
            parts[owner].append((T, r.body(links[link])))

    canonical = []
    for k, j in enumerate(actuated):
        parent_link = j.find("parent").attrib["link"]
        owner, T_parent = frames[parent_link]
        assert owner < k, "joints must be in topological order"
        axis = r.floats(j.find("axis"), "xyz", 3, "1 0 0")
        largest = float(np.abs(axis).max())
        if largest == 0:
            raise r.fail(j.find("axis"), f"joint '{j.attrib.get('name')}' has a zero axis")
        # scale by a power of two (exact) so that |axis|^2 neither overflows nor underflows
        axis = np.array([math.ldexp(float(a), -math.frexp(largest)[1]) for a in axis])
        limit = j.find("limit")
        is_continuous = j.attrib["type"] == "continuous"
        limits = Limits() if limit is None else Limits(
            lower=None if is_continuous else r.number(limit, "lower", "0"),
            upper=None if is_continuous else r.number(limit, "upper", "0"),
            velocity=r.number(limit, "velocity", "0") if "velocity" in limit.attrib else None,
            effort=r.number(limit, "effort", "0") if "effort" in limit.attrib else None,
        )
        if limits.lower is not None and limits.upper is not None and limits.lower > limits.upper:
            raise r.fail(limit, f"joint '{j.attrib.get('name')}': <limit> lower {limits.lower:g} is above "
                                f"upper {limits.upper:g}")
        for key in ("velocity", "effort"):
            if (getattr(limits, key) or 0.0) < 0:
                raise r.fail(limit, f"joint '{j.attrib.get('name')}': <limit> {key} must be >= 0")
        dyn = j.find("dynamics")
        damping = r.number(dyn, "damping", "0") if dyn is not None else 0.0
        friction = r.number(dyn, "friction", "0") if dyn is not None else 0.0
        if damping < 0 or friction < 0:
            raise r.fail(dyn, f"joint '{j.attrib.get('name')}': <dynamics> damping and friction must be >= 0")
        canonical.append(Joint(
            name=r.attr(j, "name"), type=_JOINT_TYPES[j.attrib["type"]], parent=owner,
            origin=exact.matmul(T_parent, r.origin(j)), axis=exact.unit(axis), body=merge_bodies(parts[k]),
            viscous=damping, coulomb=friction, damping=damping, limits=limits,
        ))
    return canonical, frames, locked


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
    return (f"{r.loc(foreign[0])}: note: ignored {n} element{'s' if n != 1 else ''} robotgen does not use "
            f"under <robot>: {listed}",)


def _locked_mimics(r: _Reader, mimics: list[Element]) -> tuple[str, ...]:
    """One note for the mimic joints a tree locks, in file order, at the first one's <mimic>."""
    if not mimics:
        return ()
    mimics = sorted(mimics, key=lambda j: (j.line, j.col))
    listed = ", ".join(f"'{j.attrib.get('name')}' (mimics '{j.find('mimic').attrib.get('joint', '?')}')"
                       for j in mimics)
    n = len(mimics)
    which = "the joint that mimics" if n == 1 else f"the {n} joints that mimic"
    return (f"{r.loc(mimics[0].find('mimic'))}: note: locked at q = 0 {which} another joint "
            f"(robotgen has no coupled coordinates): {listed}",)


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
    return _single_leaf_system(path, read_urdf(path, tip, base, name), name is not None)


def load_urdf_tree_system(path: str, base: str | None = None, tip: str | None = None,
                          name: str | None = None) -> RobotSystem:
    """A single-leaf system of the whole tree below ``base`` (``read_urdf_tree``)."""
    return _single_leaf_system(path, read_urdf_tree(path, base, tip, name), name is not None)


def _single_leaf_system(path: str, chain: UrdfChain, named: bool) -> RobotSystem:
    """The system of one URDF leaf; its module is named ``chain.tree.name`` made an
    identifier. Without an explicit name (``named``), a module name that differs from the
    robot's name gets a note."""
    module_name = module_identifier(chain.tree.name)
    notes = chain.notes
    if not named and module_name != chain.tree.name:
        source = (f'<robot name="{chain.robot_name}">' if chain.robot_name is not None
                  else f"the file name '{Path(path).name}'")
        notes += (f"{chain.robot or Location(path, 1, 1)}: note: module name '{module_name}' (from {source}); "
                  "pass --name to choose another",)
    node = DefineNode(module_name, chain.tree)
    sha = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return RobotSystem(module_name, path, sha, {module_name: node}, module_name, warnings=notes)


def module_identifier(name: str) -> str:
    """A module name from a robot's name: ASCII letters, digits and _, and _robot appended
    where the name would be a keyword or hide a standard name (robotgen.model.names)."""
    out = "".join(c if c.isascii() and (c.isalnum() or c == "_") else "_" for c in name.lower())[:MAX_LENGTH - 6]
    out = out if out and not out[0].isdigit() else "_" + out
    return out + "_robot" if name_problem(out) else out
