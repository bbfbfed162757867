"""Row slices of CasADi column vectors that stay columns: SX slicing of a 1 x 1 matrix
yields a 1 x 0 matrix for an empty range, which then concatenates the wrong way."""

from __future__ import annotations

import casadi as ca


def rows(x: ca.SX, start: int, stop: int | None = None) -> ca.SX:
    """Rows start..stop of x (a column or a matrix); an empty column when none."""
    stop = x.shape[0] if stop is None else stop
    if stop <= start:
        return ca.SX(0, 1)
    return x[start:stop, :] if x.shape[1] > 1 else x[start:stop]
