"""Normalise DH tables and URDF-like joint lists into canonical joints (robotgen.model.chain):

    frame(i) = frame(i-1) @ origin_i @ motion(axis_i, q_i)

Standard DH: link frame i = frame i-1 · Rz(theta+q) Tz(d) Tx(a) Rx(alpha) (Tz(d+q) if
prismatic). The motion comes first and the fixed part P_i = Rz(theta) Tz(d) Tx(a) Rx(alpha)
after it, so the canonical joint frame i sits before P_i: origin_i = P_{i-1} (P_0 = base),
axis z; link i's inertia, given after P_i, is re-expressed in joint frame i; tool' = P_n tool.

Modified DH (Craig): frame i = frame i-1 · Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i) ·
motion, and Rz(q) (or Tz(q)) commutes with the last factor, so origin_i is that product,
axis z, and the link frame is the joint frame.

Joint list (URDF): origin_i as given, axis normalised; the link frame is the joint frame.

In every convention the base transform pre-multiplies joint 1's origin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from robotgen.model.chain import Body, Joint, Limits
from robotgen.model.transforms import rot_x, rot_z, trans
from robotgen.numeric import exact

DH_STANDARD = "dh_standard"
DH_MODIFIED = "dh_modified"
JOINT_LIST = "joints"
CONVENTIONS = (DH_STANDARD, DH_MODIFIED, JOINT_LIST)

Z_AXIS = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class DHParameters:
    """One joint's DH parameters: a [m], alpha [rad], d [m], theta [rad] (the joint variable's offset)."""

    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0


@dataclass(frozen=True, eq=False)
class JointRow:
    """One joint as a spec writes it, in its convention's terms.

    dh: the row (dh_standard: a_i, alpha_i, d_i, theta_i; dh_modified: a_{i-1},
        alpha_{i-1}, d_i, theta_i). origin, axis: joint list only; axis any nonzero vector.
    body: inertial data in the convention's link frame i.
    """

    name: str
    type: str
    body: Body
    dh: DHParameters | None = None
    origin: np.ndarray | None = None
    axis: np.ndarray | None = None
    motor_inertia: float = 0.0
    gear_ratio: float = 1.0
    viscous: float = 0.0
    coulomb: float = 0.0
    limits: Limits = field(default_factory=Limits)


def unit_axis(axis) -> np.ndarray:
    """``axis`` scaled to unit length; ValueError if it is (numerically) zero."""
    v = np.asarray(axis, dtype=float)
    if exact.norm(v) < 1e-12:
        raise ValueError("joint axis must not be the zero vector")
    return exact.unit(v)


def armature(motor_inertia: float, gear_ratio: float) -> float:
    """Reflected rotor inertia on the joint side."""
    return motor_inertia * gear_ratio**2


def body_in_frame(body: Body, T: np.ndarray) -> Body:
    """``body`` given in frame B, expressed in frame A, where T = A -> B."""
    R, p = T[:3, :3], T[:3, 3]
    inertia = exact.matmul(R, body.inertia, R.T)
    return Body(body.mass, exact.add(exact.matmul(R, body.com), p), exact.add((0.5, inertia), (0.5, inertia.T)))


def dh_standard_fixed(row: DHParameters) -> np.ndarray:
    """P = Rz(theta) Tz(d) Tx(a) Rx(alpha): the part of a standard DH row after the motion."""
    return exact.matmul(rot_z(row.theta), trans(0, 0, row.d), trans(row.a, 0, 0), rot_x(row.alpha))


def dh_modified_origin(row: DHParameters) -> np.ndarray:
    """Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)."""
    return exact.matmul(rot_x(row.alpha), trans(row.a, 0, 0), rot_z(row.theta), trans(0, 0, row.d))


def _dh(row: JointRow) -> DHParameters:
    """The row's DH parameters (a DH chain's rows all have them)."""
    if row.dh is None:
        raise ValueError(f"joint '{row.name}' of a DH chain has no DH row")
    return row.dh


def _joint(row: JointRow, index: int, origin: np.ndarray, axis: np.ndarray, body: Body) -> Joint:
    return Joint(
        name=row.name,
        type=row.type,
        parent=index - 1,
        origin=origin,
        axis=axis,
        body=body,
        armature=armature(row.motor_inertia, row.gear_ratio),
        viscous=row.viscous,
        coulomb=row.coulomb,
        limits=row.limits,
    )


def dh_standard_chain(
    rows: Sequence[JointRow], base: np.ndarray, tool: np.ndarray
) -> tuple[tuple[Joint, ...], np.ndarray]:
    """Canonical joints of a standard-DH chain (Denavit-Hartenberg 1955) after ``base``, and the tip with ``tool``."""
    joints = []
    before = base  # P_{i-1}, with P_0 = base
    for i, row in enumerate(rows):
        fixed = dh_standard_fixed(_dh(row))
        joints.append(_joint(row, i, before, Z_AXIS.copy(), body_in_frame(row.body, fixed)))
        before = fixed
    return tuple(joints), exact.matmul(before, tool)


def dh_modified_chain(
    rows: Sequence[JointRow], base: np.ndarray, tool: np.ndarray
) -> tuple[tuple[Joint, ...], np.ndarray]:
    """Canonical joints of a modified-DH chain (Craig's convention) after ``base``, and the tool."""
    joints = tuple(
        _joint(
            row, i, exact.matmul(base if i == 0 else np.eye(4), dh_modified_origin(_dh(row))), Z_AXIS.copy(), row.body
        )
        for i, row in enumerate(rows)
    )
    return joints, tool.copy()


def joint_list_chain(
    rows: Sequence[JointRow], base: np.ndarray, tool: np.ndarray
) -> tuple[tuple[Joint, ...], np.ndarray]:
    """Canonical joints of a joint list (origin and axis per joint) after ``base``, and the tool."""
    joints = tuple(
        _joint(row, i, exact.matmul(base if i == 0 else np.eye(4), row.origin), unit_axis(row.axis), row.body)
        for i, row in enumerate(rows)
    )
    return joints, tool.copy()


_NORMALISERS = {DH_STANDARD: dh_standard_chain, DH_MODIFIED: dh_modified_chain, JOINT_LIST: joint_list_chain}


def canonical_chain(
    convention: str, rows: Sequence[JointRow], base: np.ndarray, tool: np.ndarray
) -> tuple[tuple[Joint, ...], np.ndarray]:
    """Canonical joints of a serial chain and the tool transform in the last joint's frame."""
    return _NORMALISERS[convention](rows, base, tool)
