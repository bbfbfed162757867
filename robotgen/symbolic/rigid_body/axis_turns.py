"""Turns about constant unit axes and products with constant vectors, on 3-vectors given as
lists of CasADi scalars. A constant's zeros are skipped and its +-1 become additions, so a
robot whose axes are coordinate axes (the usual DH arm) pays only for what is not zero."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from robotgen.numeric import exact


def dot(constant, v) -> ca.SX:
    """constant . v, skipping the constant's zeros."""
    terms = [float(k) * v[i] for i, k in enumerate(constant) if k]
    return sum(terms[1:], terms[0]) if terms else ca.SX(0)


def cross(u, v) -> list:
    """u x v of (3,) vectors as a list of entries."""
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def turn(w: Sequence[float] | np.ndarray, c, s, v) -> list:
    """Rot(w, q) v (Rodrigues), (cos q, sin q) = (c, s), constant unit w."""
    w = [float(x) for x in w]
    k = dot(w, v)
    across = cross(w, v)
    return [w[i] * k + c * (v[i] - w[i] * k) + s * across[i] for i in range(3)]


def turned_dot(w: np.ndarray, e: np.ndarray, c, s, x) -> ca.SX:
    """(Rot(w, q) e) . x for constants w, e: the component along e of Rot(w, -q) x."""
    we = exact.dot(w, e)
    return we * dot(w, x) + c * dot(exact.add(e, (-we, w)), x) + s * dot(exact.cross(w, e), x)


def plane_turn(c, s, u, v) -> tuple:
    """(u, v) turned by q in its plane, (c, s) = (cos q, sin q)."""
    return c * u - s * v, s * u + c * v
