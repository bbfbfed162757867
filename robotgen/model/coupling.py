"""Mimic joints as reduced coordinates.

A tree keeps every physical joint. A mimic joint (URDF <mimic>, an MJCF joint equality
constraint) moves as an affine function of the joint it follows, q_i = m_i q_leader + c_i.
Following the leaders to a joint that follows none gives each joint its independent
coordinate, and the joints' positions, rates and accelerations are

    q_joints = S q + c,    qd_joints = S qd,    qdd_joints = S qdd,

with S (joints x coordinates) holding one entry per row, the product of the multipliers along
the way in the column of joint i's coordinate (1 for the coordinate's own joint), and c the
offsets carried along (q_3 = m_3 (m_2 q_1 + c_2) + c_3). S is constant, so the reduced
Lagrangian L(S q + c, S qd) gives M_r = S^T M S, C_r = S^T C S, N_r = S^T N and the work of
the joint forces tau^T S qd gives tau_r = S^T tau (robotgen.symbolic.rigid_body.coupled).

The composed multipliers and offsets are exact (rationals on the file's doubles), rounded once,
so they are the same on every machine.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np


@dataclass(frozen=True)
class Mimic:
    """Joint ``joint`` follows joint ``leader`` (indices into the tree's joints) as its source
    states it: q_joint = multiplier q_leader + offset."""

    joint: int
    leader: int
    multiplier: float
    offset: float


class MimicCycle(ValueError):
    """Mimic joints that follow each other round a cycle (joint indices, in the order followed)."""

    def __init__(self, joints: tuple[int, ...]):
        super().__init__(f"mimic joints follow each other in a cycle: {joints}")
        self.joints = joints


@dataclass(frozen=True, eq=False)
class Coupling:
    """q_joints = S q + c: per joint, the coordinate that moves it, its multiplier and offset."""

    independent: tuple[int, ...]  # the joint of each coordinate, in the tree's joint order
    coordinate: tuple[int, ...]  # per joint: the index of its coordinate
    multiplier: tuple[float, ...]  # per joint: the entry of S (1.0 for a coordinate's own joint)
    offset: tuple[float, ...]  # per joint: c (0.0 for a coordinate's own joint)

    @property
    def nq(self) -> int:
        """The number of coordinates (independent joints)."""
        return len(self.independent)

    def matrix(self) -> np.ndarray:
        """S, joints x coordinates."""
        S = np.zeros((len(self.coordinate), self.nq))
        S[np.arange(len(self.coordinate)), self.coordinate] = self.multiplier
        return S

    def offsets(self) -> np.ndarray:
        """c of q_joints = S q + c: (n_joints,) offsets [rad or m]."""
        return np.array(self.offset, dtype=float)

    def joints_of(self, k: int) -> list[int]:
        """The joints coordinate k moves, in joint order (its own among them)."""
        return [i for i, c in enumerate(self.coordinate) if c == k]

    def followers(self) -> list[int]:
        """The joints that are not a coordinate's own."""
        own = set(self.independent)
        return [i for i in range(len(self.coordinate)) if i not in own]


def affine(multiplier: float, leader: str, offset: float) -> str:
    """``multiplier * leader + offset`` as a reader writes it: -1 * 'a' - 0.2, 'a' alone for 1 and 0."""
    text = leader if multiplier == 1.0 else f"{multiplier:g} * {leader}"
    return text if offset == 0.0 else f"{text} {'-' if offset < 0 else '+'} {abs(offset):g}"


def couple(n_joints: int, mimics: list[Mimic]) -> Coupling | None:
    """The coupling of ``n_joints`` joints of which ``mimics`` follow others (at most one mimic
    per joint); None without mimics. Raises MimicCycle when following the leaders returns to a
    joint already passed."""
    if not mimics:
        return None
    follows = {m.joint: m for m in sorted(mimics, key=lambda m: m.joint)}
    resolved: dict[int, tuple[int, Fraction, Fraction]] = {}  # joint -> (own joint, multiplier, offset)

    def resolve(i: int) -> tuple[int, Fraction, Fraction]:
        path: list[int] = []
        j = i
        while j in follows and j not in resolved:
            if j in path:
                raise MimicCycle(tuple(path[path.index(j) :]))
            path.append(j)
            j = follows[j].leader
        own, m, c = resolved.get(j, (j, Fraction(1), Fraction(0)))
        for k in reversed(path):  # q_k = m_k q_leader + c_k = (m_k m) q_own + (m_k c + c_k)
            step = follows[k]
            mk = Fraction(step.multiplier)
            m, c = mk * m, mk * c + Fraction(step.offset)
            resolved[k] = (own, m, c)
        return own, m, c

    rows = [resolve(i) for i in range(n_joints)]
    independent = tuple(i for i in range(n_joints) if i not in follows)
    index = {joint: k for k, joint in enumerate(independent)}
    return Coupling(
        independent,
        tuple(index[own] for own, _, _ in rows),
        tuple(float(m) for _, m, _ in rows),
        tuple(float(c) for _, _, c in rows),
    )
