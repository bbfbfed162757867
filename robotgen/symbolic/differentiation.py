"""Derivatives of SX graphs by CasADi's algorithmic differentiation, in the sweep order that
suits their shape."""

from __future__ import annotations

import casadi as ca


def reverse_jacobian(e: ca.SX, x: ca.SX) -> ca.SX:
    """de/dx by one reverse sweep per entry of e (cheaper than forward sweeps when x is longer,
    and for recursive algorithms such as Newton-Euler, whose reverse sweep shares the forward
    pass)."""
    n = e.shape[0]
    return ca.vertcat(*[ca.jtimes(e, x, ca.DM.eye(n)[:, k], True).T for k in range(n)])
