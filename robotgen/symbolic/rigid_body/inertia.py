"""Rigid-body inertia about a frame origin, as (m, h = m c, Ibar = Ic + m(|c|^2 I - c c^T)),
the form in which bodies are combined by the composite rigid body algorithm; its constants come
from robotgen.model.regrouping (a body's own, or regrouped)."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from robotgen.model.regrouping import OriginParameters
from robotgen.symbolic.rigid_body.spatial import const, rotate_symmetric


@dataclass(frozen=True, eq=False)
class OriginInertia:
    """A body's inertia about a frame origin: mass m [kg], first moment h = m c (3,) [kg m], Ibar (3, 3) [kg m^2]."""

    m: ca.SX
    h: ca.SX  # (3,) first mass moment m c
    Ibar: ca.SX  # (3, 3) rotational inertia about the frame origin

    @staticmethod
    def constant(p: OriginParameters) -> OriginInertia:
        """The SX form of constant origin parameters."""
        return OriginInertia(ca.SX(p.mass), const(p.first_moment), const(p.inertia))

    SIZE = 13  # as a column: m, h, Ibar (by columns)

    def vector(self) -> ca.SX:
        """(13,): m, h, then Ibar by columns."""
        return ca.vertcat(self.m, self.h, ca.vec(self.Ibar))

    @staticmethod
    def of_vector(x: ca.SX) -> OriginInertia:
        """The inertia a (13,) column holds (inverse of vector)."""
        return OriginInertia(x[0], x[1:4], ca.reshape(x[4:13], 3, 3))

    def scaled(self, k: float) -> OriginInertia:
        """The inertia scaled by k (mass, moment and Ibar)."""
        return OriginInertia(k * self.m, k * self.h, k * self.Ibar)

    def apply6(self, x: ca.SX) -> ca.SX:
        """apply on a stacked 6-vector (angular; linear)."""
        return ca.vertcat(*self.apply(x[:3], x[3:]))

    def apply(self, w: ca.SX, v: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Spatial momentum of the motion (w, v): (Ibar w + h x v, m v - h x w)."""
        return self.Ibar @ w + ca.cross(self.h, v), self.m * v - ca.cross(self.h, w)

    def to_parent(self, m) -> OriginInertia:
        """Express about the parent origin of joint motion ``m``: X^T I X with
        X = [E 0; -E skew(r) E]."""
        Ibar = m.turn_symmetric(self.Ibar)
        return self._shifted(m.to_parent(self.h), rotate_symmetric(m.R0, Ibar), m.r)

    def in_frame(self, R: ca.SX, p: ca.SX) -> OriginInertia:
        """Express about the origin of a frame in which this one has orientation R and origin p."""
        return self._shifted(R @ self.h, rotate_symmetric(R, self.Ibar), p)

    def _shifted(self, h_rot: ca.SX, I_rot: ca.SX, r: ca.SX) -> OriginInertia:
        """From (h, Ibar) already rotated into the new axes, about an origin displaced by -r:
        Ibar + m (|r|^2 1 - r r^T) + 2 (r . h) 1 - r h^T - h r^T, formed on its upper triangle."""
        rr = ca.dot(r, r)
        rh = ca.dot(r, h_rot)
        Ibar = ca.SX.zeros(3, 3)
        for i in range(3):
            for j in range(i, 3):
                shift = -(self.m * r[i] * r[j]) - (r[i] * h_rot[j] + h_rot[i] * r[j])
                Ibar[i, j] = Ibar[j, i] = I_rot[i, j] + (shift + self.m * rr + 2 * rh if i == j else shift)
        return OriginInertia(self.m, h_rot + self.m * r, Ibar)

    def __add__(self, other: OriginInertia) -> OriginInertia:
        return OriginInertia(self.m + other.m, self.h + other.h, self.Ibar + other.Ibar)
