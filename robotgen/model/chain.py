"""Kinematic trees of rigid bodies in one canonical form.

Every way of describing a chain (DH standard, DH modified, URDF-style joint list) is
normalised into this form, so the symbolic algorithms know only one convention:

    frame(i) = frame(parent(i)) @ joint.origin @ motion(joint.axis, q_i)

where ``motion`` is a rotation about ``axis`` (revolute) or a translation along it
(prismatic), both in joint i's frame. Link i is rigidly attached to frame(i); its
inertial data is expressed in frame(i). The base frame is frame(-1) = identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from robotgen.model.coupling import Coupling
from robotgen.numeric import exact

REVOLUTE = "revolute"
PRISMATIC = "prismatic"
JOINT_TYPES = (REVOLUTE, PRISMATIC)
# deviations from physical consistency that a spec may keep on purpose (published parameter
# sets carry them), acknowledged per inertia with ``accept``
TRIANGLE_INEQUALITY = "triangle_inequality"
ACCEPTABLE_DEVIATIONS = (TRIANGLE_INEQUALITY,)


@dataclass(frozen=True, eq=False)
class Body:
    """Rigid-body inertia: mass [kg], centre of mass [m] and inertia tensor about the COM
    [kg m^2], both in the frame of the joint that carries the body."""

    mass: float
    com: np.ndarray  # (3,)
    inertia: np.ndarray  # (3, 3) symmetric, about the COM

    @staticmethod
    def zero() -> Body:
        """A massless body."""
        return Body(0.0, np.zeros(3), np.zeros((3, 3)))


@dataclass(frozen=True)
class Limits:
    """A joint's limits as the file gives them: lower, upper [rad or m], velocity [rad/s or m/s], effort [N m or N]."""

    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None


@dataclass(frozen=True, eq=False)
class Joint:
    """One actuated joint with the body it carries.

    armature: reflected motor inertia added on the diagonal of M (motor inertia * gear^2).
    viscous, coulomb: joint-side friction, tau_f = viscous * qd + coulomb * tanh(qd / smoothing).
    """

    name: str
    type: str  # REVOLUTE or PRISMATIC
    parent: int  # index of the parent joint, -1 for the base
    origin: np.ndarray  # (4, 4) parent frame -> this joint's frame at q = 0
    axis: np.ndarray  # (3,) unit vector in this joint's frame
    body: Body
    armature: float = 0.0
    viscous: float = 0.0
    coulomb: float = 0.0
    damping: float = 0.0  # URDF <dynamics damping>, kept apart for info(); folded into viscous
    limits: Limits = field(default_factory=Limits)


@dataclass(frozen=True, eq=False)
class KinematicTree:
    """Joints in topological order (parent index < own index). A serial chain has
    parent(i) = i - 1. The tip frame is ``tool`` expressed in joint ``tip``'s frame."""

    name: str
    joints: tuple[Joint, ...]
    tip: int  # index of the joint whose frame carries the tool frame
    tool: np.ndarray  # (4, 4) joint frame(tip) -> tip frame
    gravity: np.ndarray  # (3,) gravitational acceleration in the base frame, e.g. (0, 0, -9.81)
    coulomb_smoothing: float = 1e-2  # [rad/s or m/s] velocity scale of tanh in Coulomb friction
    base_link: str = "base"
    tip_link: str = "tip"
    locked_joints: tuple[str, ...] = ()  # movable joints of the source held at q = 0 (URDF)
    coupling: Coupling | None = None  # mimic joints: q_joints = S q + c (model/coupling.py)

    @property
    def nq(self) -> int:
        """Number of coordinates: the joints, less those that mimic another."""
        return len(self.joints) if self.coupling is None else self.coupling.nq

    @property
    def n_joints(self) -> int:
        """Number of physical joints, the size the rigid-body algorithms work in."""
        return len(self.joints)

    @property
    def coordinate_joints(self) -> tuple[Joint, ...]:
        """The joint of each coordinate (every joint without a coupling): its name, type and
        limits are the coordinate's."""
        if self.coupling is None:
            return self.joints
        return tuple(self.joints[i] for i in self.coupling.independent)

    def support(self, i: int) -> list[int]:
        """Joints from the base to joint i, inclusive, base first."""
        path = []
        while i >= 0:
            path.append(i)
            i = self.joints[i].parent
        return path[::-1]

    @property
    def has_friction(self) -> bool:
        """Whether any joint has viscous or Coulomb friction."""
        return any(j.viscous or j.coulomb for j in self.joints)


def coordinate_axis(axis: np.ndarray) -> int | None:
    """k when the unit ``axis`` is +e_k or -e_k (exactly, as snapping leaves it), else None."""
    k = [i for i in range(3) if abs(float(axis[i])) == 1.0]
    return k[0] if k else None


def with_payload(tree: KinematicTree, mass: float, point: np.ndarray) -> KinematicTree:
    """The same tree with a point mass added to the body of joint ``tree.tip`` at ``point``
    (in that joint's frame): a payload held at the hand."""
    joints = list(tree.joints)
    j = joints[tree.tip]
    b = j.body
    total = b.mass + mass
    if total == 0:
        return tree
    com = exact.add((b.mass / total, b.com), (mass / total, np.asarray(point, dtype=float)))
    inertia = exact.add(
        exact.parallel_axis(b.inertia, b.mass, exact.add(b.com, (-1.0, com))),
        exact.parallel_axis(np.zeros((3, 3)), mass, exact.add(point, (-1.0, com))),
    )
    joints[tree.tip] = replace(j, body=Body(total, com, inertia))
    return replace(tree, joints=tuple(joints))


def mimic_joints(tree: KinematicTree) -> str:
    """The joints that follow another's coordinate, named and quoted for a message."""
    followers = tree.coupling.followers() if tree.coupling is not None else []
    return ", ".join(f"'{tree.joints[i].name}'" for i in followers)


def joints_without_inertia(tree: KinematicTree) -> list[int]:
    """Joints that move no mass and no inertia: their subtree (the joint's body and every body
    after it) is massless with zero rotational inertia, and they have no armature. Their row of
    M is zero at every configuration, so M is singular and forward dynamics has no answer.
    Under a coupling, a joint counts when every joint of its coordinate does (then the
    coordinate's row of S^T M S is zero)."""
    carried = [0.0] * len(tree.joints)
    for i in reversed(range(len(tree.joints))):
        joint = tree.joints[i]
        carried[i] += joint.body.mass + float(np.abs(joint.body.inertia).sum())
        if joint.parent >= 0:
            carried[joint.parent] += carried[i]
    empty = [carried[i] == 0.0 and joint.armature == 0.0 for i, joint in enumerate(tree.joints)]
    if tree.coupling is not None:
        c = tree.coupling.coordinate
        empty = [all(empty[j] for j in tree.coupling.joints_of(c[i])) for i in range(len(empty))]
    return [i for i, e in enumerate(empty) if e]
