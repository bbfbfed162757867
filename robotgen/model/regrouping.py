"""Inertial parameters regrouped along the tree (Khalil and Kleinfinger 1987): the same joint
torques from fewer non-zero constants.

Each body is held as (m, h = m c, Ibar), its inertia about its joint's origin in its joint's
frame. The torques of a fixed-base tree depend on these only through its Lagrangian, and part
of a body's inertia adds to the Lagrangian exactly what it would add carried by the parent:

- revolute joint about axis a: the mass, the first moment along a, and Ibar's part
  alpha (1 - a a^T). A body of these parameters is unchanged by the joint's rotation, its
  potential energy does not depend on q_i, and |w|^2 - (w . a)^2 is the same for the body's
  angular velocity w and its parent's (they differ by qd_i a). With a along a coordinate
  axis k and alpha the Ibar entry of the next-but-one axis (k + 2 mod 3), that entry, m and
  h_k become exactly 0: Khalil's XXR = XX - YY and the moves of YY, MZ and M for a = z;
- prismatic joint: all of Ibar (the body turns with its parent).

From the tips down, each body's movable part is carried across its joint's constant origin
into the parent's parameters; what reaches the fixed base moves nothing and is dropped. The
regrouped parameters are not a physical body (m = 0 with h != 0), and every algorithm that
reads them must be linear in (m, h, Ibar): composite rigid bodies, Newton-Euler about the
frame origin, the spatial Coriolis matrix and the derivative recursions are.

The arithmetic is exact (rationals on the model's doubles) and each parameter is rounded once,
so the printed constants are the same on every machine.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from robotgen.model.chain import PRISMATIC, Body, KinematicTree, coordinate_axis

_Vector = list[Fraction]
_Matrix = list[list[Fraction]]


@dataclass(frozen=True, eq=False)
class OriginParameters:
    """Inertia about a joint frame's origin, in that frame: mass, first moment m c and
    rotational inertia Ibar = Ic + m (|c|^2 1 - c c^T)."""

    mass: float
    first_moment: np.ndarray  # (3,)
    inertia: np.ndarray  # (3, 3) symmetric


@dataclass
class _Exact:
    m: Fraction
    h: _Vector
    I: _Matrix

    def plus(self, other: _Exact) -> _Exact:
        return _Exact(
            self.m + other.m,
            [a + b for a, b in zip(self.h, other.h)],
            [[a + b for a, b in zip(r, s)] for r, s in zip(self.I, other.I)],
        )

    def rounded(self) -> OriginParameters:
        return OriginParameters(
            float(self.m), np.array([float(x) for x in self.h]), np.array([[float(x) for x in row] for row in self.I])
        )


def _exact(a) -> list:
    a = np.asarray(a, dtype=float)
    return [Fraction(float(x)) for x in a] if a.ndim == 1 else [_exact(row) for row in a]


def _of_body(body: Body) -> _Exact:
    m, c, Ic = Fraction(float(body.mass)), _exact(body.com), _exact(body.inertia)
    cc = sum(x * x for x in c)
    I = [[Ic[i][j] + m * ((cc if i == j else 0) - c[i] * c[j]) for j in range(3)] for i in range(3)]
    return _Exact(m, [m * x for x in c], I)


def _split(p: _Exact, joint_type: str, axis: np.ndarray) -> tuple[_Exact, _Exact]:
    """(kept, moved) with kept + moved = p; moved is unchanged by the joint's motion."""
    if joint_type == PRISMATIC:
        moved = _Exact(Fraction(0), [Fraction(0)] * 3, [row[:] for row in p.I])
    else:
        k = coordinate_axis(axis)
        moved = _Exact(p.m, [Fraction(0)] * 3, [[Fraction(0)] * 3 for _ in range(3)])
        if k is not None:  # about a coordinate axis: the axial first moment and alpha (1 - a a^T) too
            moved.h[k] = p.h[k]
            alpha = p.I[(k + 2) % 3][(k + 2) % 3]
            for i in range(3):
                if i != k:
                    moved.I[i][i] = alpha
    kept = _Exact(
        p.m - moved.m,
        [a - b for a, b in zip(p.h, moved.h)],
        [[a - b for a, b in zip(r, s)] for r, s in zip(p.I, moved.I)],
    )
    return kept, moved


def _to_parent(p: _Exact, origin: np.ndarray) -> _Exact:
    """The same inertia about the parent frame's origin, in its axes: the joint frame sits at
    r with orientation R0 there (the joint's own motion leaves a moved part unchanged)."""
    R, r = _exact(origin[:3, :3]), _exact(origin[:3, 3])
    h = [sum(R[i][k] * p.h[k] for k in range(3)) for i in range(3)]
    RI = [[sum(R[i][k] * p.I[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    I = [[sum(RI[i][k] * R[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    rr = sum(x * x for x in r)
    rh = sum(a * b for a, b in zip(r, h))
    shifted = [
        [
            I[i][j] - p.m * r[i] * r[j] - r[i] * h[j] - h[i] * r[j] + ((p.m * rr + 2 * rh) if i == j else 0)
            for j in range(3)
        ]
        for i in range(3)
    ]
    return _Exact(p.m, [a + p.m * b for a, b in zip(h, r)], shifted)


def origin_parameters(body: Body) -> OriginParameters:
    """A body's own (m, h, Ibar) about its joint's origin, not regrouped."""
    return _of_body(body).rounded()


def regrouped_inertias(tree: KinematicTree) -> list[OriginParameters]:
    """Each joint's regrouped (m, h, Ibar) in its own frame, about its origin."""
    params = [_of_body(j.body) for j in tree.joints]
    for i in reversed(range(tree.n_joints)):
        joint = tree.joints[i]
        params[i], moved = _split(params[i], joint.type, np.asarray(joint.axis, dtype=float))
        if joint.parent >= 0:
            params[joint.parent] = params[joint.parent].plus(_to_parent(moved, joint.origin))
    return [p.rounded() for p in params]
