"""Read an MJCF file (MuJoCo's XML) into a KinematicTree: the chain of hinge and slide joints
from a base body to a tip body or site (``read_mjcf``), or every such joint below a base body
(``read_mjcf_tree``).

The file is compiled by MuJoCo itself (``mujoco.MjSpec.from_file`` and ``compile``, the
parser and compiler behind ``mujoco.MjModel.from_xml_path``), so defaults classes, includes,
``fromto``, quaternions, ``euler`` with the compiler's ``angle`` and ``eulerseq``, inertias
inferred from geoms and every ``<compiler>`` option mean what MuJoCo says. robotgen reads the
compiled quantities only: body_pos/body_quat, jnt_pos/jnt_axis, qpos0, body_ipos/body_iquat,
body_inertia, body_mass, dof_armature, dof_damping, dof_frictionloss, jnt_range, site_pos/
site_quat and opt.gravity. The spec is kept for the line of each element in messages (MuJoCo
records it; an element from an included file has none and is located at the file's start).
``mujoco`` is an optional dependency, imported here only.

Frames (MuJoCo's mj_kinematics): a body's frame is its parent's frame moved by (body_pos,
body_quat), then by each of its joints in order: a hinge turns it by qpos - qpos0 about the
axis through jnt_pos, a slide moves it by qpos - qpos0 along the axis. Each hinge or slide
becomes one canonical joint (several joints in one body: a chain of them with massless bodies
between), its frame at the anchor jnt_pos with the body's orientation, and its origin turned
(moved) by -qpos0, so that robotgen's q is MuJoCo's qpos of the same joint: q = qpos,
qd = qvel, tau = qfrc_applied. qpos0 is the joint's ``ref``; the file draws the bodies at
qpos = qpos0.

Normalisation:
- bodies without joints are welded to their parent: their inertia merges into the body of
  the nearest kept joint above them (or is dropped when they hang from the base);
- chain: hinge and slide joints of bodies off the base -> tip path that the chain carries
  (a gripper's fingers) are held at q = 0 (qpos = 0; a ball joint at the identity) and listed
  in ``KinematicTree.locked_joints``; bodies below the base that the chain does not carry
  (the scene's objects, another arm) do not move with it and are left out, named in a note;
- tree: every hinge and slide joint below the base is kept, in MuJoCo's order (depth first);
- the base body is held where its joints (above the base) put it at q = 0 (qpos = 0 for a hinge
  or slide, qpos0 for a ball or free joint, which is where the file draws it), and gravity is
  opt.gravity turned into its frame (zero when the option disables gravity);
- dof_armature is the armature added to M's diagonal (as MuJoCo does); dof_damping is viscous
  friction; dof_frictionloss becomes robotgen's smooth Coulomb friction
  frictionloss * tanh(qd / coulomb_smoothing) (a note says so: MuJoCo's friction loss is a
  constraint force bounded by frictionloss, which also holds a joint at rest);
- jnt_range is the joint's limits when jnt_limited; a symmetric actuator force range is its
  effort limit.

A joint equality constraint with a linear polynomial is read as a mimic joint, exactly
(``mjcf_equality``): joint1 stays a joint, moved by joint2's coordinate; a chain keeps the joints
so coupled to its path.

Refused, naming the element: a ball or free joint that robotgen would have to keep (on the
chain, or below the base of a tree), a free joint carried by the chain, an active equality
constraint that acts on the kept joints and is not such a coupling, a flex, a tip or base that is not in the model, a
tip not below the base, non-finite or huge numbers, negative damping, armature or friction
loss. Ignored with a warning naming them: joint stiffness, gravity compensation, fluid
forces and tendons' stiffness, damping and friction loss acting on the kept joints; with a
note: actuators (robotgen's inputs are joint forces) and equality constraints that do not act
on the kept joints. Contacts and the limit constraints are not part of robotgen's dynamics.
"""

from __future__ import annotations

import hashlib
import math
import re
import warnings
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from robotgen.errors import MUJOCO_INSTALL, Location, MissingDependency, UserError
from robotgen.frontend.input_file import read_input
from robotgen.frontend.mjcf_equality import (
    JointEquality,
    coupled_note,
    coupling_of,
    joint_equalities,
    leading_joints,
    refuse_touching,
)
from robotgen.frontend.urdf import merge_bodies, module_identifier
from robotgen.model.chain import PRISMATIC, REVOLUTE, Body, Joint, KinematicTree, Limits, joints_without_inertia
from robotgen.model.expression import MAX_MAGNITUDE
from robotgen.model.system import DefineNode, RobotSystem
from robotgen.model.transforms import trans
from robotgen.numeric import exact

# mjtJoint and mjtEq values (MuJoCo's ABI)
FREE, BALL, SLIDE, HINGE = 0, 1, 2, 3
_JOINT_WORDS = {FREE: "a free joint", BALL: "a ball joint"}
_CONNECT, _WELD, _JOINT_EQ, _TENDON_EQ = 0, 1, 2, 3
_OBJ_SITE = 6  # mjOBJ_SITE: a connect or weld between sites
_WRAP_JOINT, _WRAP_SITE, _WRAP_SPHERE, _WRAP_CYLINDER = 1, 3, 4, 5
MAX_BYTES = 16_000_000
DEFAULT_MODEL_NAME = "MuJoCo Model"  # what MuJoCo calls a model without <mujoco model=...>


@dataclass(frozen=True, eq=False)
class MjcfRobot:
    """A tree read from an MJCF file, with the located notes and warnings for the user;
    ``model_name`` is <mujoco model=...> (None when the file has none)."""

    tree: KinematicTree
    notes: tuple[str, ...]
    model_name: str | None
    root: Location  # where <mujoco> starts
    digest: str  # sha256 of the file and of every compiled quantity robotgen read


class _Mjcf:
    """The compiled model, its spec (for lines) and the main file's text (for columns)."""

    def __init__(
        self,
        mujoco,
        path: str,
        spec,
        model,
        lines: list[str],
        said: list[str],
        disabled: dict[str, bool],
        drawn: set[str],
    ):
        self.mujoco, self.path, self.spec, self.m, self.lines = mujoco, path, spec, model, lines
        self.warnings = said  # MuJoCo's own warnings, located at the file
        self.disabled = disabled  # <option><flag>s that switch off what robotgen reads
        self.joint_names = _joint_names(model)
        self.drawn_bodies = drawn  # the bodies of the file, fused ones included

    def name(self, kind: str, i: int) -> str:
        """The element's name, or "<kind> <id>" for an unnamed one."""
        return self.given_name(kind, i) or f"{kind} {i}"

    def given_name(self, kind: str, i: int) -> str:
        obj = getattr(self.mujoco.mjtObj, f"mjOBJ_{kind.upper()}")
        return self.mujoco.mj_id2name(self.m, obj, i) or ""

    def loc(self, kind: str, i: int) -> Location:
        """Where the element stands in the file: MuJoCo's line (spec.info), the column of
        its tag on that line; without a line (a <freejoint>), the first tag of its kind with
        its name; an element of an included file at the file's start."""
        spec_element = next((e for e in getattr(self.spec, _SPEC_LISTS[kind]) if e.id == i), None)
        match = re.search(r"line (\d+)", getattr(spec_element, "info", "") or "")
        line = int(match.group(1)) if match else 0
        tags = _TAGS.get(kind, kind)
        if 0 < line <= len(self.lines):
            col = re.search(rf"<(?:{tags})\b", self.lines[line - 1]) or re.search("<", self.lines[line - 1])
            return Location(self.path, line, col.start() + 1 if col else 1)
        name = self.given_name(kind, i)
        if name:
            pattern = re.compile(rf"<(?:{tags})\b[^>]*\bname\s*=\s*[\"']{re.escape(name)}[\"']")
            for n, text in enumerate(self.lines, 1):
                found = pattern.search(text)
                if found:
                    return Location(self.path, n, found.start() + 1)
        return self.root_loc()

    def root_loc(self) -> Location:
        for n, text in enumerate(self.lines, 1):
            col = text.find("<mujoco")
            if col >= 0:
                return Location(self.path, n, col + 1)
        return Location(self.path, 1, 1)

    def fail(self, kind: str, i: int, message: str) -> UserError:
        return UserError(self.loc(kind, i), message)


_SPEC_LISTS = {
    "body": "bodies",
    "joint": "joints",
    "site": "sites",
    "equality": "equalities",
    "tendon": "tendons",
    "actuator": "actuators",
    "flex": "flexes",
}
# tags of each kind (regular expressions); equality constraints, tendons and actuators have
# a tag per type (<weld>, <fixed>, <motor>, ...)
_TAGS = {"joint": "joint|freejoint", "flex": "flex|flexcomp", "equality": r"\w+", "tendon": r"\w+", "actuator": r"\w+"}


# what each <option><flag> switches off; older MuJoCo releases had one flag, PASSIVE, for springs
# and dampers
_DISABLE_BITS = {
    "gravity": ("GRAVITY",),
    "damper": ("DAMPER", "PASSIVE"),
    "spring": ("SPRING", "PASSIVE"),
    "frictionloss": ("FRICTIONLOSS",),
    "constraint": ("CONSTRAINT",),
}


def _compile(path: str) -> _Mjcf:
    """MuJoCo's compiler on ``path``; a file MuJoCo refuses is a UserError with its message,
    at the line MuJoCo names."""
    try:
        import mujoco
    except ImportError:
        raise MissingDependency(f"reading an MJCF file needs MuJoCo: {MUJOCO_INSTALL}") from None
    text = read_input(path, MAX_BYTES, "MJCF file").decode("utf-8", errors="replace")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            spec = mujoco.MjSpec.from_file(str(path))
            drawn = {body.name for body in spec.bodies}  # before the compiler fuses any away
            model = spec.compile()
        except ValueError as e:
            raise _refused(path, text.splitlines(), str(e)) from None
    said = [f"{Location(path)}: warning: MuJoCo: {w.message}" for w in caught]
    flags = int(model.opt.disableflags)
    disabled = {
        key: any(flags & int(getattr(mujoco.mjtDisableBit, f"mjDSBL_{bit}", 0)) for bit in bits)
        for key, bits in _DISABLE_BITS.items()
    }
    return _Mjcf(mujoco, path, spec, model, text.splitlines(), said, disabled, drawn)


def _refused(path: str, lines: list[str], message: str) -> UserError:
    """MuJoCo's message, at the line it names (its XML parser says "Line number=N", its
    schema check and compiler "line N"), the column of the element it names."""
    match = re.search(r"[Ll]ine(?: number=| )(\d+)", message)
    line = int(match.group(1)) if match else 1
    col = 1
    if 0 < line <= len(lines):  # the element's tag, or the line's first one
        element = re.search(r"Element '(\w+)'|XMLElement name=(\w+)", message)
        found = lines[line - 1].find(f"<{element.group(1) or element.group(2)}" if element else "<")
        col = found + 1 if found >= 0 else 1
    text = "; ".join(part.strip() for part in message.strip().splitlines() if part.strip())
    return UserError(Location(path, max(line, 1), col), f"MuJoCo cannot compile this file: {text}")


# -- constant geometry, exact (robotgen.numeric.exact): the same bits on every machine -------------
def _quat_rotation(q) -> np.ndarray:
    """The rotation of a unit quaternion (w, x, y, z), MuJoCo's convention:
    R = (w^2 - v.v) E + 2 v v^T + 2 w [v]x."""
    w, x, y, z = (float(c) for c in q)
    d = exact.dot
    return np.array(
        [
            [d((w, x, -y, -z), (w, x, y, z)), d((x, -w), (y, z)) * 2, d((x, w), (z, y)) * 2],
            [d((x, w), (y, z)) * 2, d((w, -x, y, -z), (w, x, y, z)), d((y, -w), (z, x)) * 2],
            [d((x, -w), (z, y)) * 2, d((y, w), (z, x)) * 2, d((w, -x, -y, z), (w, x, y, z))],
        ]
    )


def _pose(pos, quat) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = _quat_rotation(quat), np.asarray(pos, dtype=float)
    return T


def _turn(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues): c E + s [a]x + (1 - c) a a^T."""
    if angle == 0.0:
        return np.eye(4)
    s, c = exact.sin_cos(angle)
    a = [float(v) for v in axis]
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    T = np.eye(4)
    T[:3, :3] = exact.add((c, np.eye(3)), (s, K), (float(Fraction(1) - Fraction(c)), exact.outer(a, a)))
    return T


def _motion(jtype: int, axis, value: float) -> np.ndarray:
    """A hinge turned or a slide moved by ``value`` (exactly as the canonical joint would)."""
    if jtype == HINGE:
        return _turn(axis, value)
    return trans(*(float(Fraction(float(value)) * Fraction(float(a))) for a in axis))


def _body(mj: _Mjcf, b: int) -> Body:
    """Body b's inertia in its own frame: mass, body_ipos, body_inertia about the principal
    axes body_iquat."""
    m = mj.m
    R = _quat_rotation(m.body_iquat[b])
    inertia = exact.matmul(R, np.diag(m.body_inertia[b].astype(float)), R.T)
    return Body(float(m.body_mass[b]), m.body_ipos[b].astype(float).copy(), inertia)


def _check_numbers(mj: _Mjcf) -> None:
    """Every number robotgen reads is finite and at most MAX_MAGNITUDE (MuJoCo accepts 1e300
    and some NaNs); damping, armature and friction loss are not negative; no flex."""
    m = mj.m
    per_kind = {
        "body": ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_inertia", "body_mass"),
        "joint": ("jnt_pos", "jnt_axis", "qpos0", "jnt_range", "dof_armature", "dof_damping", "dof_frictionloss"),
        "site": ("site_pos", "site_quat"),
    }
    for kind, fields in per_kind.items():
        count = {"body": m.nbody, "joint": m.njnt, "site": m.nsite}[kind]
        for i in range(count):
            for field in fields:
                values = _field(m, field, i)
                if not all(math.isfinite(v) and abs(v) <= MAX_MAGNITUDE for v in values):
                    raise mj.fail(
                        kind,
                        i,
                        f"{kind} '{mj.name(kind, i)}': MuJoCo's compiled {field} holds "
                        f"{' '.join(f'{v:g}' for v in values)}; robotgen reads finite numbers "
                        f"up to {MAX_MAGNITUDE:g} in magnitude",
                    )
                if field in ("dof_armature", "dof_damping", "dof_frictionloss") and min(values, default=0.0) < 0:
                    raise mj.fail(
                        kind, i, f"joint '{mj.name(kind, i)}': {field.split('_')[1]} {min(values):g} is negative"
                    )
    if m.nflex:
        raise mj.fail("flex", 0, f"flex '{mj.name('flex', 0)}': deformable bodies are not part of robotgen's model")
    g = [float(v) for v in m.opt.gravity]
    if not all(math.isfinite(v) and abs(v) <= MAX_MAGNITUDE for v in g):
        raise UserError(
            mj.root_loc(),
            f"<option gravity> holds {' '.join(map(str, g))}; robotgen reads finite "
            f"numbers up to {MAX_MAGNITUDE:g} in magnitude",
        )


def _field(m, field: str, i: int) -> list[float]:
    """Row i (a joint's, for the qpos and dof fields: only hinge and slide have one each)."""
    if field == "qpos0":
        return [float(v) for v in m.qpos0[m.jnt_qposadr[i] : m.jnt_qposadr[i] + _nq(int(m.jnt_type[i]))]]
    if field.startswith("dof_"):
        return [float(v) for v in getattr(m, field)[m.jnt_dofadr[i] : m.jnt_dofadr[i] + _nv(int(m.jnt_type[i]))]]
    return [float(v) for v in np.atleast_1d(getattr(m, field)[i])]


def _nq(jtype: int) -> int:
    return {FREE: 7, BALL: 4}.get(jtype, 1)


def _nv(jtype: int) -> int:
    return {FREE: 6, BALL: 3}.get(jtype, 1)


# -- the model's structure ------------------------------------------------------------------------
def _ancestors(m, b: int) -> list[int]:
    """Bodies from b up to the world, b first."""
    out = [b]
    while out[-1] != 0:
        out.append(int(m.body_parentid[out[-1]]))
    return out


def _joints_of(m, b: int) -> range:
    start = int(m.body_jntadr[b])
    return range(start, start + int(m.body_jntnum[b])) if start >= 0 else range(0)


def _find(mj: _Mjcf, label: str, name: str, sites: bool) -> tuple[int, int | None]:
    """(body, site or None) named ``name``: a body first, then (``sites``) a site."""
    mujoco = mj.mujoco
    b = mujoco.mj_name2id(mj.m, mujoco.mjtObj.mjOBJ_BODY, name)
    if b >= 0:
        return b, None
    s = mujoco.mj_name2id(mj.m, mujoco.mjtObj.mjOBJ_SITE, name) if sites else -1
    if s >= 0:
        return int(mj.m.site_bodyid[s]), s
    fused = name in mj.drawn_bodies
    what = "body or site" if sites else "body"
    why = (
        ' (MuJoCo\'s compiler fused it into its parent: <compiler fusestatic="true">; name a site on it or its parent)'
        if fused
        else ""
    )
    raise UserError(mj.root_loc(), f"{label} {what} '{name}' is not in the model{why}")


@dataclass
class _Plan:
    """The base body, the joints robotgen keeps (MuJoCo's order), the bodies below the base
    (MuJoCo's topological order) and the joint equality constraints read as couplings."""

    base: int
    kept: list[int]
    below: list[int]
    equalities: tuple[JointEquality, ...] = ()


def _frames(mj: _Mjcf, plan: _Plan) -> tuple[list[Joint], dict[int, tuple[int, np.ndarray]], list[int]]:
    """Canonical joints for ``plan.kept``, each body's frame below the base as (owner: the
    index of the kept joint it moves with, or -1 for the base; T owner -> body), and the
    joints held at q = 0 on bodies that move with a kept joint (a free joint there is an
    error)."""
    m = mj.m
    index = {j: k for k, j in enumerate(plan.kept)}
    frames: dict[int, tuple[int, np.ndarray]] = {plan.base: (-1, np.eye(4))}
    origins: list[tuple[int, int, np.ndarray]] = []  # per kept joint: (joint id, parent index, origin)
    locked: list[int] = []
    for b in plan.below:
        owner, T = frames[int(m.body_parentid[b])]
        T = exact.matmul(T, _pose(m.body_pos[b], m.body_quat[b]))
        for j in _joints_of(m, b):
            jtype, anchor = int(m.jnt_type[j]), m.jnt_pos[j].astype(float)
            axis = m.jnt_axis[j].astype(float)
            ref = float(m.qpos0[m.jnt_qposadr[j]]) if jtype in (HINGE, SLIDE) else 0.0
            if j in index:  # the joint's frame at its anchor, turned back by qpos0: q = qpos
                at = trans(*anchor) if jtype == HINGE else np.eye(4)
                origins.append((j, owner, exact.matmul(T, at, _motion(jtype, axis, -ref))))
                owner, T = index[j], (trans(*(-anchor)) if jtype == HINGE else np.eye(4))
                continue
            if owner >= 0:
                if jtype == FREE:
                    raise _refuse_joint(mj, j, "carried by the chain")
                locked.append(j)
            if jtype in (HINGE, SLIDE):  # held at qpos = 0: moved by 0 - qpos0 about its anchor
                T = exact.matmul(T, trans(*anchor), _motion(jtype, axis, -ref), trans(*(-anchor)))
            # a ball joint held at the identity quaternion does not move its body, nor does a
            # free joint of a body that the base holds (it is not part of the model)
        frames[b] = (owner, T)
    parts: list[list[tuple[np.ndarray, Body]]] = [[] for _ in plan.kept]
    for b in plan.below:
        owner, T = frames[b]
        if owner >= 0:
            parts[owner].append((T, _body(mj, b)))
    joints = []
    for k, (j, parent, origin) in enumerate(origins):
        jtype, dof = int(m.jnt_type[j]), int(m.jnt_dofadr[j])
        damping = 0.0 if mj.disabled["damper"] else float(m.dof_damping[dof])
        friction = 0.0 if mj.disabled["frictionloss"] or mj.disabled["constraint"] else float(m.dof_frictionloss[dof])
        joints.append(
            Joint(
                name=mj.joint_names[j],
                type=REVOLUTE if jtype == HINGE else PRISMATIC,
                parent=parent,
                origin=origin,
                axis=exact.unit(m.jnt_axis[j].astype(float)),
                body=merge_bodies(parts[k]),
                armature=float(m.dof_armature[dof]),
                viscous=damping,
                coulomb=friction,
                damping=damping,
                limits=_limits(m, j),
            )
        )
    return joints, frames, locked


def _limits(m, j: int) -> Limits:
    lower = upper = effort = None
    if m.jnt_limited[j]:
        lower, upper = (float(v) for v in m.jnt_range[j])
    if m.jnt_actfrclimited[j]:
        lo, hi = (float(v) for v in m.jnt_actfrcrange[j])
        effort = hi if lo == -hi else None
    return Limits(lower=lower, upper=upper, effort=effort)


def _joint_names(m) -> list[str]:
    """Every joint's name; an unnamed joint is called after its body (``<body>_joint<k>``),
    made unique against the named ones."""
    names = [m.joint(j).name for j in range(m.njnt)]
    taken = set(names)
    for j, name in enumerate(names):
        if not name:
            b = int(m.jnt_bodyid[j])
            base = f"{m.body(b).name or f'body{b}'}_joint{j - int(m.body_jntadr[b])}"
            candidate, n = base, 1
            while candidate in taken:
                candidate, n = f"{base}_{n}", n + 1
            names[j] = candidate
            taken.add(candidate)
    return names


def _base_pose(mj: _Mjcf, base: int) -> np.ndarray:
    """The base body's frame in the world with the joints above it at q = 0 (qpos = 0 for a
    hinge or slide, qpos0 for a ball or free joint: the identity turn, or the pose the file
    draws)."""
    m = mj.m
    T = np.eye(4)
    for b in reversed(_ancestors(m, base)[:-1]):
        T = exact.matmul(T, _pose(m.body_pos[b], m.body_quat[b]))
        for j in _joints_of(m, b):
            jtype, adr = int(m.jnt_type[j]), int(m.jnt_qposadr[j])
            if jtype == FREE:  # qpos is the body's pose in the world
                T = _pose(m.qpos0[adr : adr + 3], m.qpos0[adr + 3 : adr + 7])
            elif jtype == BALL:
                R = np.eye(4)
                R[:3, :3] = _quat_rotation(m.qpos0[adr : adr + 4])
                anchor = m.jnt_pos[j].astype(float)
                T = exact.matmul(T, trans(*anchor), R, trans(*(-anchor)))
            else:
                anchor, axis = m.jnt_pos[j].astype(float), m.jnt_axis[j].astype(float)
                T = exact.matmul(T, trans(*anchor), _motion(jtype, axis, -float(m.qpos0[adr])), trans(*(-anchor)))
    return T


def _gravity(mj: _Mjcf, base: int) -> np.ndarray:
    if mj.disabled["gravity"]:
        return np.zeros(3)
    R = _base_pose(mj, base)[:3, :3]
    return exact.matmul(R.T, mj.m.opt.gravity.astype(float))


# -- what robotgen does not model -----------------------------------------------------------------
def _acts_on(owners: list[int | None]) -> bool:
    """A constraint or force between bodies (given by their owners: a kept joint's index, -1
    for the base, None for a body not below it) acts on the model when one of them moves with
    a kept joint and they do not all move together."""
    return any(o is not None and o >= 0 for o in owners) and len(set(owners)) > 1


def _tendon_parts(m, t: int) -> tuple[list[int], list[int]]:
    """(joints, bodies) a tendon's path goes through."""
    joints, bodies = [], []
    for w in range(int(m.tendon_adr[t]), int(m.tendon_adr[t]) + int(m.tendon_num[t])):
        kind, obj = int(m.wrap_type[w]), int(m.wrap_objid[w])
        if kind == _WRAP_JOINT:
            joints.append(obj)
        elif kind == _WRAP_SITE:
            bodies.append(int(m.site_bodyid[obj]))
        elif kind in (_WRAP_SPHERE, _WRAP_CYLINDER):
            bodies.append(int(m.geom_bodyid[obj]))
    return joints, bodies


def _unmodelled(mj: _Mjcf, plan: _Plan, frames: dict) -> tuple[str, ...]:
    """An error for an active equality constraint that acts on the model; warnings for the
    forces robotgen leaves out that act on it; notes for the rest."""
    m = mj.m
    kept = set(plan.kept)
    coupled = {q.equality for q in _couplings(plan)}
    owner = {b: frames[b][0] if b in frames else None for b in range(m.nbody)}

    def tendon_acts(t: int) -> bool:
        joints, bodies = _tendon_parts(m, t)
        return any(j in kept for j in joints) or _acts_on([owner[b] for b in bodies])

    ignored = []
    for e in range(m.neq):
        kind, a, b = int(m.eq_type[e]), int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        if kind in (_CONNECT, _WELD):  # between bodies (or sites), -1 being the world
            body = (lambda i: int(m.site_bodyid[i])) if int(m.eq_objtype[e]) == _OBJ_SITE else (lambda i: i)
            acts = _acts_on([owner[body(i)] if i >= 0 else owner[0] for i in (a, b)])
        elif kind == _JOINT_EQ:  # a joint held fixed cannot move, whatever the polynomial says
            if e in coupled:
                continue
            acts = a in kept or b in kept
        elif kind == _TENDON_EQ:
            acts = any(tendon_acts(t) for t in (a, b) if t >= 0)
        else:  # flexes are refused above; a distance constraint (removed from MuJoCo) acts
            acts = True
        if acts and m.eq_active0[e]:
            raise mj.fail(
                "equality",
                e,
                f"equality constraint '{mj.name('equality', e)}' acts on the joints "
                "robotgen keeps, and robotgen has no constraints inside a chain or tree "
                "(choose a tip or a base that leaves them out)",
            )
        ignored.append(e)
    notes: list[str] = []
    if ignored:
        names = ", ".join(f"'{mj.name('equality', e)}'" for e in ignored)
        many = len(ignored) != 1
        notes.append(
            f"{mj.loc('equality', ignored[0])}: note: ignored {len(ignored)} equality constraint"
            f"{'s' if many else ''} that do{'' if many else 'es'} not act on the joints robotgen keeps "
            f"(inactive, or among parts held fixed): {names}"
        )
    moving = [b for b in plan.below if frames[b][0] >= 0]
    warned = []
    stiff = [j for j in plan.kept if m.jnt_stiffness[j] != 0 and not mj.disabled["spring"]]
    if stiff:
        warned.append(
            (
                mj.loc("joint", stiff[0]),
                "the joint stiffness (springs) of " + ", ".join(f"'{mj.joint_names[j]}'" for j in stiff),
            )
        )
    gravcomp = [b for b in moving if m.body_gravcomp[b] != 0]
    if gravcomp:
        warned.append(
            (
                mj.loc("body", gravcomp[0]),
                "the gravity compensation (gravcomp) of " + ", ".join(f"'{mj.name('body', b)}'" for b in gravcomp),
            )
        )
    if (m.opt.density or m.opt.viscosity) and moving:
        warned.append(
            (
                mj.root_loc(),
                f'fluid forces (<option density="{float(m.opt.density):g}" viscosity="{float(m.opt.viscosity):g}">)',
            )
        )
    passive = [
        t
        for t in range(m.ntendon)
        if (m.tendon_stiffness[t] or m.tendon_damping[t] or m.tendon_frictionloss[t]) and tendon_acts(t)
    ]
    if passive:
        warned.append(
            (
                mj.loc("tendon", passive[0]),
                "the stiffness, damping and friction loss of tendons "
                + ", ".join(f"'{mj.name('tendon', t)}'" for t in passive),
            )
        )
    notes += [f"{where}: warning: ignored {what}: robotgen's model has no such forces" for where, what in warned]
    if m.nu:
        notes.append(
            f"{mj.loc('actuator', 0)}: note: ignored {m.nu} actuator{'s' if m.nu != 1 else ''}: "
            "robotgen's inputs are the joint forces tau (MuJoCo's qfrc_applied)"
        )
    return tuple(notes)


def _couplings(plan: _Plan) -> list[JointEquality]:
    """The joint equality constraints read as couplings of kept joints."""
    kept = set(plan.kept)
    return [q for q in plan.equalities if q.problem is None and q.joint in kept]


def _with_coupled(mj: _Mjcf, base: int, below: list[int], moving: list[int]) -> _Plan:
    """The plan of the joints ``moving`` (MuJoCo's order) and every hinge and slide joint below
    the base coupled to them by joint equality constraints (mjcf_equality): the other finger of
    a chain to one finger, the leader off the chain of a joint on it."""
    m = mj.m
    hinges = {j for b in below for j in _joints_of(m, b) if int(m.jnt_type[j]) in (HINGE, SLIDE)}
    equalities = joint_equalities(mj, hinges, mj.name("body", base))
    ends = leading_joints(mj, equalities)
    coordinates = {ends.get(j, j) for j in moving}
    kept = sorted(set(moving) | {j for j in hinges if ends.get(j, j) in coordinates})
    refuse_touching(mj, equalities, set(kept))
    return _Plan(base, kept, below, tuple(equalities))


def _friction_note(mj: _Mjcf, tree: KinematicTree, kept: list[int]) -> tuple[str, ...]:
    rubbing = [(j, joint) for j, joint in zip(kept, tree.joints) if joint.coulomb]
    if not rubbing:
        return ()
    listed = ", ".join(f"'{joint.name}' {joint.coulomb:g}" for _, joint in rubbing)
    return (
        f"{mj.loc('joint', rubbing[0][0])}: note: frictionloss becomes Coulomb friction "
        f"frictionloss * tanh(qd / {tree.coulomb_smoothing:g}) ({listed}); MuJoCo's friction loss is a "
        "constraint force up to frictionloss that can also hold the joint at rest",
    )


# -- readers --------------------------------------------------------------------------------------
def _below(m, base: int) -> list[int]:
    return [b for b in range(1, m.nbody) if b != base and base in _ancestors(m, b)[1:]]


def _refuse_joint(mj: _Mjcf, j: int, why: str) -> UserError:
    jtype = int(mj.m.jnt_type[j])
    hint = f"; read the tree below it with --base {mj.name('body', int(mj.m.jnt_bodyid[j]))}" if jtype == FREE else ""
    return mj.fail(
        "joint",
        j,
        f"joint '{mj.joint_names[j]}' is {_JOINT_WORDS[jtype]} ({why}), which robotgen does not support{hint}",
    )


def _robot(mj: _Mjcf, plan: _Plan, tip: tuple[int, int | None] | None, name: str | None, chain: bool) -> MjcfRobot:
    """The tree of ``plan``; its tip the body (and site) ``tip``, or for None the first leaf
    body that moves with a kept joint."""
    m = mj.m
    joints, frames, locked = _frames(mj, plan)
    site: int | None = None
    if tip is None:
        parents = {int(m.body_parentid[b]) for b in range(1, m.nbody)}
        leaf_body = next((b for b in plan.below if b not in parents and frames[b][0] >= 0), None)
        if leaf_body is None:
            raise mj.fail(
                "body",
                plan.base,
                f"no body below base body '{mj.name('body', plan.base)}' moves with a joint robotgen keeps",
            )
        tip_body = leaf_body
    else:
        tip_body, site = tip
    tip_name = mj.name("site", site) if site is not None else mj.name("body", tip_body)
    if frames.get(tip_body, (-1,))[0] < 0:
        where = "is not below" if tip_body not in frames else "does not move below"
        raise mj.fail("body", tip_body, f"tip '{tip_name}' {where} base body '{mj.name('body', plan.base)}'")
    owner, tool = frames[tip_body]
    if site is not None:
        tool = exact.matmul(tool, _pose(m.site_pos[site], m.site_quat[site]))
    model_name = mj.spec.modelname if mj.spec.modelname != DEFAULT_MODEL_NAME else None
    tree = KinematicTree(
        name=name or model_name or Path(mj.path).stem,
        joints=tuple(joints),
        tip=owner,
        tool=tool,
        gravity=_gravity(mj, plan.base),
        base_link=mj.name("body", plan.base),
        tip_link=tip_name,
        locked_joints=tuple(mj.joint_names[j] for j in locked),
        coupling=coupling_of(plan.kept, plan.equalities),
    )
    notes = tuple(mj.warnings)
    left_out = [j for b in plan.below if frames[b][0] < 0 for j in _joints_of(m, b)]
    if chain and left_out:
        notes += (
            f"{mj.loc('joint', left_out[0])}: note: left out {len(left_out)} joint"
            f"{'s' if len(left_out) != 1 else ''} of bodies that do not move with the chain: "
            + ", ".join(f"'{mj.joint_names[j]}'" for j in left_out),
        )
    notes += coupled_note(mj, _couplings(plan)) + _unmodelled(mj, plan, frames) + _friction_note(mj, tree, plan.kept)
    notes += tuple(
        f"{mj.loc('joint', plan.kept[i])}: warning: joint '{tree.joints[i].name}' moves no mass or "
        "inertia (massless bodies after it): M is singular and forward dynamics returns no finite answer"
        for i in joints_without_inertia(tree)
    )
    return MjcfRobot(tree, notes, model_name, mj.root_loc(), _digest(mj, bool(_couplings(plan))))


def read_mjcf(path: str, tip: str, base: str | None = None, name: str | None = None) -> MjcfRobot:
    """The chain of hinge and slide joints from body ``base`` (default: the world) to the body
    or site ``tip``. Joints that the chain carries off its path are held at q = 0."""
    mj = _compile(path)
    _check_numbers(mj)
    m = mj.m
    tip_body, site = _find(mj, "tip", tip, sites=True)
    base_body = _find(mj, "base", base, sites=False)[0] if base is not None else 0
    path_bodies = _ancestors(m, tip_body)
    if base_body not in path_bodies[1:]:
        raise mj.fail("body", tip_body, f"tip '{tip}' is not below base body '{mj.name('body', base_body)}'")
    path_bodies = path_bodies[: path_bodies.index(base_body)][::-1]  # base (exclusive) -> tip
    on_path = [j for b in path_bodies for j in _joints_of(m, b)]
    for j in on_path:
        if int(m.jnt_type[j]) in (BALL, FREE):
            raise _refuse_joint(mj, j, f"on the chain from '{mj.name('body', base_body)}' to '{tip}'")
    if not on_path:
        raise mj.fail("body", tip_body, f"no joint between '{mj.name('body', base_body)}' and '{tip}'")
    return _robot(mj, _with_coupled(mj, base_body, _below(m, base_body), on_path), (tip_body, site), name, chain=True)


def read_mjcf_tree(path: str, base: str | None = None, tip: str | None = None, name: str | None = None) -> MjcfRobot:
    """Every hinge and slide joint below body ``base`` (default: the world), in MuJoCo's
    order. The fk/Jacobian tip is the body or site ``tip``, or the first leaf body (a body
    without children) in that order that moves with a joint."""
    mj = _compile(path)
    _check_numbers(mj)
    m = mj.m
    base_body = _find(mj, "base", base, sites=False)[0] if base is not None else 0
    below = _below(m, base_body)
    kept = []
    for b in below:
        for j in _joints_of(m, b):
            if int(m.jnt_type[j]) in (BALL, FREE):
                raise _refuse_joint(mj, j, f"below the base body '{mj.name('body', base_body)}'")
            kept.append(j)
    if not kept:
        raise UserError(
            mj.root_loc() if base_body == 0 else mj.loc("body", base_body),
            f"no joint below base body '{mj.name('body', base_body)}'",
        )
    tip_at = _find(mj, "tip", tip, sites=True) if tip is not None else None
    return _robot(mj, _with_coupled(mj, base_body, below, kept), tip_at, name, chain=False)


def _digest(mj: _Mjcf, equalities: bool) -> str:
    """sha256 of the file and of every compiled array robotgen reads: an included file or a
    mesh that changes the model changes it (the build cache's key and the manifest's
    spec_sha256). ``equalities``: joint equality constraints were read as couplings."""
    m = mj.m
    h = hashlib.sha256(Path(mj.path).read_bytes())
    for field in (
        "body_parentid",
        "body_jntadr",
        "body_jntnum",
        "body_pos",
        "body_quat",
        "body_ipos",
        "body_iquat",
        "body_inertia",
        "body_mass",
        "jnt_type",
        "jnt_pos",
        "jnt_axis",
        "qpos0",
        "jnt_limited",
        "jnt_range",
        "dof_armature",
        "dof_damping",
        "dof_frictionloss",
        "site_bodyid",
        "site_pos",
        "site_quat",
    ):
        h.update(field.encode() + np.ascontiguousarray(getattr(m, field)).tobytes())
    if equalities:
        for field_name in ("eq_type", "eq_obj1id", "eq_obj2id", "eq_active0", "eq_data"):
            h.update(field_name.encode() + np.ascontiguousarray(getattr(m, field_name)).tobytes())
    h.update(np.ascontiguousarray(m.opt.gravity).tobytes() + int(m.opt.disableflags).to_bytes(8, "little"))
    h.update("\0".join(mj.joint_names).encode() + "\0".join(m.body(b).name for b in range(m.nbody)).encode())
    return h.hexdigest()


# -- systems --------------------------------------------------------------------------------------
def load_mjcf_system(path: str, tip: str, base: str | None = None, name: str | None = None) -> RobotSystem:
    """A single-leaf system of the chain to ``tip`` (``read_mjcf``)."""
    return _single_leaf_system(path, read_mjcf(path, tip, base, name), name is not None)


def load_mjcf_tree_system(
    path: str, base: str | None = None, tip: str | None = None, name: str | None = None
) -> RobotSystem:
    """A single-leaf system of the whole tree below ``base`` (``read_mjcf_tree``)."""
    return _single_leaf_system(path, read_mjcf_tree(path, base, tip, name), name is not None)


def _single_leaf_system(path: str, robot: MjcfRobot, named: bool) -> RobotSystem:
    """The module is named after <mujoco model> (else the file's name) made an identifier;
    without --name, a module name that differs from it gets a note."""
    module_name = module_identifier(robot.tree.name)
    notes = robot.notes
    if not named and module_name != robot.tree.name:
        source = (
            f'<mujoco model="{robot.model_name}">'
            if robot.model_name is not None
            else f"the file name '{Path(path).name}'"
        )
        notes += (f"{robot.root}: note: module name '{module_name}' (from {source}); pass --name to choose another",)
    return RobotSystem(
        module_name, path, robot.digest, {module_name: DefineNode(module_name, robot.tree)}, module_name, warnings=notes
    )
