"""Read a URDF file into a KinematicTree: the chain of movable joints from a base link to a
tip link (``read_urdf``), or every movable joint below a base link (``read_urdf_tree``, e.g.
a humanoid's joints below its pelvis).

Parsed with the standard library's expat (to keep line numbers) into plain elements, then
checked against the subset of URDF robotgen understands: an element or joint type outside
it is an error naming the element, never skipped silently. Known URDF elements without
dynamic meaning (visual, collision, material, transmission, gazebo, calibration,
safety_controller) are accepted and not used.

Normalisation (into robotgen.model.chain's canonical form):
- fixed joints are folded away: the inertia of every link they carry is merged into the
  body of the nearest movable joint above it (or dropped when it is fixed to the base);
- chain: movable joints that are not on the base -> tip path (a gripper's fingers) are locked
  at q = 0 and treated as fixed; they are listed in ``KinematicTree.locked_joints``;
- tree: all movable joints below the base are kept, in depth-first order with parent indices;
- URDF <dynamics damping> becomes viscous friction, <dynamics friction> Coulomb friction.
"""
from __future__ import annotations

import hashlib
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robotgen.errors import Location, UserError
from robotgen.model.chain import PRISMATIC, REVOLUTE, Body, Joint, KinematicTree, Limits
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.model.transforms import xyz_rpy

_IGNORED = {"visual", "collision", "material", "transmission", "gazebo", "calibration",
            "safety_controller", "sensor"}
_CHILDREN = {
    "robot": {"link", "joint"} | _IGNORED,
    "link": {"inertial"} | _IGNORED,
    "inertial": {"origin", "mass", "inertia"},
    "joint": {"origin", "parent", "child", "axis", "limit", "dynamics", "mimic"} | _IGNORED,
}
_JOINT_TYPES = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC, "fixed": None}
_UNSUPPORTED_TYPES = {"floating": "a floating joint", "planar": "a planar joint"}


@dataclass
class Element:
    tag: str
    attrib: dict[str, str]
    line: int
    col: int
    children: list["Element"] = field(default_factory=list)

    def find(self, tag: str) -> "Element | None":
        return next((c for c in self.children if c.tag == tag), None)


def _parse_xml(path: str, data: bytes) -> Element:
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Element] = []
    root: list[Element] = []

    def start(tag, attrib):
        el = Element(tag, dict(attrib), parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        (stack[-1].children if stack else root).append(el)
        stack.append(el)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as e:
        raise UserError(Location(path, e.lineno, e.offset + 1),
                        f"not well-formed XML: {xml.parsers.expat.ErrorString(e.code)}") from None
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

    def floats(self, el: Element | None, name: str, n: int, default: str) -> np.ndarray:
        text = default if el is None else self.attr(el, name, default)
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != n:
            raise self.fail(el, f"<{el.tag}> attribute '{name}' must hold {n} numbers, got '{text}'")
        return np.array(values)

    def number(self, el: Element, name: str, default: str | None = None) -> float:
        return float(self.floats(el, name, 1, self.attr(el, name, default))[0])

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
        return Body(mass, T[:3, 3].copy(), R @ I @ R.T)


def merge_bodies(parts: list[tuple[np.ndarray, Body]]) -> Body:
    """One body equal to rigidly joined bodies, each given with the transform from the
    common frame to its own frame (parallel-axis theorem)."""
    placed = []
    for T, b in parts:
        R = T[:3, :3]
        placed.append((b.mass, R @ b.com + T[:3, 3], R @ b.inertia @ R.T))
    mass = sum(m for m, _, _ in placed)
    if mass == 0:
        return Body.zero()
    com = sum(m * c for m, c, _ in placed) / mass
    inertia = np.zeros((3, 3))
    for m, c, I in placed:
        d = c - com
        inertia += I + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return Body(mass, com, inertia)


@dataclass(frozen=True, eq=False)
class UrdfChain:
    tree: KinematicTree
    ignored_attributes: tuple[str, ...]


def read_urdf(path: str, tip: str, base: str | None = None, name: str | None = None) -> UrdfChain:
    """The chain of movable joints from ``base`` (default: the root link) to ``tip``; movable
    joints off that path are locked at q = 0."""
    r, links, joints, parent_of, _ = _read_links_and_joints(path, floating_ok=False)
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
    _reject_mimic(r, actuated, "on the chain")
    canonical, frames, locked = _normalise(r, links, joints, parent_of, base, actuated)
    tip_owner, tool = frames[tip]
    robot_name = name or root.attrib.get("name", Path(path).stem)
    tree = KinematicTree(
        name=robot_name, joints=tuple(canonical), tip=tip_owner, tool=tool,
        gravity=np.array([0.0, 0.0, -9.81]), base_link=base, tip_link=tip, locked_joints=tuple(locked),
    )
    ignored = _foreign_dynamics_attributes(r, actuated)
    return UrdfChain(tree, ignored)


def read_urdf_tree(path: str, base: str | None = None, tip: str | None = None,
                   name: str | None = None) -> UrdfChain:
    """The whole tree of movable joints below ``base`` (default: the root link), e.g. every
    joint of a humanoid below its pelvis.

    Joints are in depth-first order (children in the order their joints appear in the file),
    so a joint's parent index is always smaller than its own; fixed joints are folded as in
    ``read_urdf`` and nothing is locked. Links and joints not below ``base`` are not read
    (their inertia does not move with any joint). The fk/Jacobian tip is the link ``tip``,
    or, if none is given, the first leaf link (a link without child joints) in that order
    that some movable joint carries.

    Errors (each naming the element): a mimic joint anywhere below the base (it would couple
    two coordinates); a floating or planar joint below the base. A humanoid whose URDF roots
    it with a floating joint (world -> pelvis) is read with ``base`` = the floating joint's
    child link, which gives the fixed-base tree below it."""
    r, links, joints, parent_of, floating = _read_links_and_joints(path, floating_ok=True)
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
    actuated = [joints[l] for l in order[1:] if joints[l].attrib["type"] != "fixed"]
    if not actuated:
        raise UserError(r.loc(links[base]), f"no movable joint below base link '{base}'")
    _reject_mimic(r, actuated, "in a tree (it couples two coordinates)")
    canonical, frames, locked = _normalise(r, links, joints, parent_of, base, actuated)
    assert not locked
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
        gravity=np.array([0.0, 0.0, -9.81]), base_link=base, tip_link=tip,
    )
    return UrdfChain(tree, _foreign_dynamics_attributes(r, actuated))


def _read_links_and_joints(path: str, floating_ok: bool):
    """(reader, links by name, joint element by child link, parent link by child link,
    floating joints). A floating joint is an error unless ``floating_ok`` (then it is
    returned, for the caller to accept only above its base)."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise UserError(Location(path, 1, 1), f"cannot read URDF file: {e.strerror}") from None
    root = _parse_xml(path, data)
    r = _Reader(path, root)
    r.check_children(root)
    links = {}
    for el in root.children:
        if el.tag == "link":
            lname = r.attr(el, "name")
            if lname in links:
                raise r.fail(el, f"duplicate link '{lname}'")
            links[lname] = el
    joints = {}  # child link -> joint element
    floating = []
    for el in root.children:
        if el.tag != "joint":
            continue
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
    return r, links, joints, parent_of, floating


def _reject_mimic(r: _Reader, actuated: list[Element], where: str) -> None:
    for j in actuated:
        mimic = j.find("mimic")
        if mimic is not None:
            raise r.fail(mimic, f"joint '{j.attrib.get('name')}' is a mimic joint, which robotgen "
                                f"does not support {where}")


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
                frames[child] = (owner, T @ r.origin(j))  # a locked joint sits at q = 0
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
        norm = np.linalg.norm(axis)
        if norm == 0:
            raise r.fail(j.find("axis"), f"joint '{j.attrib.get('name')}' has a zero axis")
        limit = j.find("limit")
        is_continuous = j.attrib["type"] == "continuous"
        limits = Limits() if limit is None else Limits(
            lower=None if is_continuous else r.number(limit, "lower", "0"),
            upper=None if is_continuous else r.number(limit, "upper", "0"),
            velocity=r.number(limit, "velocity", "0") if "velocity" in limit.attrib else None,
            effort=r.number(limit, "effort", "0") if "effort" in limit.attrib else None,
        )
        dyn = j.find("dynamics")
        damping = r.number(dyn, "damping", "0") if dyn is not None else 0.0
        friction = r.number(dyn, "friction", "0") if dyn is not None else 0.0
        canonical.append(Joint(
            name=r.attr(j, "name"), type=_JOINT_TYPES[j.attrib["type"]], parent=owner,
            origin=T_parent @ r.origin(j), axis=axis / norm, body=merge_bodies(parts[k]),
            viscous=damping, coulomb=friction, damping=damping, limits=limits,
        ))
    return canonical, frames, locked


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
    return _single_leaf_system(path, read_urdf(path, tip, base, name))


def load_urdf_tree_system(path: str, base: str | None = None, tip: str | None = None,
                          name: str | None = None) -> RobotSystem:
    """A single-leaf system of the whole tree below ``base`` (``read_urdf_tree``)."""
    return _single_leaf_system(path, read_urdf_tree(path, base, tip, name))


def _single_leaf_system(path: str, chain: UrdfChain) -> RobotSystem:
    module_name = _identifier(chain.tree.name)
    node = DefineNode(module_name, chain.tree)
    sha = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return RobotSystem(module_name, path, sha, {module_name: node}, module_name,
                       warnings=chain.ignored_attributes)


def _identifier(name: str) -> str:
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in name.lower())
    return out if out and not out[0].isdigit() else "_" + out
