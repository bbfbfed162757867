"""Linearised dynamics about a nominal posture and an optimal regulator on it (Whitney 1972,
eqs 19-20), computed at build time.

State s = (dtheta, dtheta_dot), deviations from the nominal (theta0, 0) held by the torque
tau0 = N(theta0, 0) (gravity). The model is the chain's symbolic forward dynamics
qdd = M^-1 (tau - C qd - N), differentiated (CasADi AD) at the nominal:

    sdot = [0 I; -M^-1 K  -M^-1 B] s + [0; M^-1] dtau          (eq 19)

K = dN/dtheta (gravity stiffness, and springs if the model had any), B = dN/dtheta_dot
(viscous and linearised Coulomb friction); the Coriolis terms vanish at zero rate.

The regulator dtau = -K_lqr s minimises the integral of s^T Q s + dtau^T R dtau; the
continuous algebraic Riccati equation is solved by robotgen.numeric.riccati, whose result is
the same on every machine (the gains are printed into the C). Controllability of (A, B) and observability of
(A, [I 0]) -- from dtheta alone, as the paper claims -- are checked by the
Popov-Belevitch-Hautus test (rank [A - lambda I, B] at every eigenvalue lambda of A), which
stays reliable where the Kalman matrix [B AB ... A^(2n-1) B] is badly scaled. The report's
eigenvalue figures come from LAPACK and are printed to 4 significant digits.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from robotgen.model.chain import KinematicTree
from robotgen.model.laws.resolved_rate import LQRSettings
from robotgen.numeric.riccati import gain, solve_care
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols


@dataclass(frozen=True, eq=False)
class Linearisation:
    """The chain's dynamics linearised at a nominal pose: A (2n, 2n), B (2n, n), nominal (n,) [rad], tau0 (n,) [N m]."""

    A: np.ndarray  # (2n, 2n)
    B: np.ndarray  # (2n, n)
    nominal: np.ndarray  # (n,)
    tau0: np.ndarray  # (n,)


@dataclass(frozen=True, eq=False)
class RegulatorDesign:
    """An LQR design on eq 19 (Whitney 1972): the model, K (n, 2n), the weights Q and R, its report."""

    model: Linearisation
    K: np.ndarray  # (n, 2n), dtau = -K s
    Q: np.ndarray
    R: np.ndarray
    report: dict


def linearise(tree: KinematicTree, nominal: np.ndarray) -> Linearisation:
    """The chain's dynamics linearised at ``nominal`` (n,) joint positions, qd = 0, with the holding torque."""
    n = tree.nq
    sym = Symbols.make(n)
    g = ChainGraphs(tree, sym)
    state = ca.vertcat(sym.q, sym.qd)
    sdot = ca.vertcat(sym.qd, g.forward_dynamics())
    f = ca.Function(
        "linearise", [sym.q, sym.qd, sym.tau], [ca.jacobian(sdot, state), ca.jacobian(sdot, sym.tau), g.nonlinear()]
    )
    zero = np.zeros(n)
    tau0 = np.array(f(nominal, zero, zero)[2]).ravel()
    A, B, _ = (np.array(x) for x in f(nominal, zero, tau0))
    return Linearisation(A, B, np.asarray(nominal, float), tau0)


def pbh_rank(A: np.ndarray, M: np.ndarray, *, rows: bool) -> int:
    """min over eigenvalues lambda of A of rank [A - lambda I, M] (rows=False: M beside,
    controllability) or rank [A - lambda I; M] (rows=True: M below, observability)."""
    n = A.shape[0]
    ranks = []
    for lam in np.linalg.eigvals(A):
        P = A - lam * np.eye(n)
        ranks.append(np.linalg.matrix_rank(np.vstack([P, M]) if rows else np.hstack([P, M])))
    return int(min(ranks))


@functools.lru_cache(maxsize=8)
def regulator(tree: KinematicTree, settings: LQRSettings) -> RegulatorDesign:
    """The LQR of the linearised chain: K from the continuous Riccati equation, its closed-loop poles."""
    n = tree.nq
    model = linearise(tree, settings.nominal)
    Q, R = np.diag(settings.q_weights), np.diag(settings.r_weights)
    K = gain(model.B, R, solve_care(model.A, model.B, Q, R))
    closed = np.linalg.eigvals(model.A - model.B @ K)
    C = np.hstack([np.eye(n), np.zeros((n, n))])
    report: dict[str, Any] = {
        "state": "(dtheta, dtheta_dot) about the nominal (Whitney 1972, eqs 19-20)",
        "state_dimension": 2 * n,
        "controllability_rank": pbh_rank(model.A, model.B, rows=False),
        "observability_rank_from_positions": pbh_rank(model.A, C, rows=True),
        "closed_loop_max_real_part": float(f"{closed.real.max():.4g}"),
        "open_loop_max_real_part": float(f"{np.linalg.eigvals(model.A).real.max():.4g}"),
    }
    report["controllable"] = report["controllability_rank"] == 2 * n
    report["observable_from_positions"] = report["observability_rank_from_positions"] == 2 * n
    report["stable"] = report["closed_loop_max_real_part"] < 0
    return RegulatorDesign(model, K, Q, R, report)
