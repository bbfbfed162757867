"""Swing-up of the planar two-link arm by iLQR, with the generated derivatives.

    python examples/trajectory_optimisation.py [--plot FILE.png]   (default generated/trajectory_optimisation.png)

The arm (specs/two_link.yaml, gravity in the plane of motion) starts hanging still,
q = (-pi/2, 0), and must be upright and still, q = (pi/2, 0), after 3 s, with at most 10 N m
per joint: less than the 13.7 N m that holding the stretched arm level takes, so it has to
swing. The model is the
generated `discrete_dynamics` (semi-implicit Euler at 100 Hz, tau held over each step), and
iLQR (iterative LQR: a Riccati sweep on the linearised model, then a forward rollout with a
line search) needs its Jacobians A = d x+/d x and B = d x+/d tau at every knot. Those come
from one batched call of `discrete_dynamics_derivatives` per iteration. The same solve is run
a second time with A and B from central finite differences of `discrete_dynamics` (also
batched), and the two are compared: cost per iteration, and solve time.

Cost: sum_k (u_k^T R u_k + (x_k - x*)^T Q (x_k - x*)) dt + (x_N - x*)^T Qf (x_N - x*), with
the torque limit kept by clamping in the rollout (the plot shows it reached).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from robotgen.cli import main as robotgen  # noqa: E402

DT, STEPS, LIMIT = 0.01, 300, 10.0
X_GOAL = np.array([np.pi / 2, 0.0, 0.0, 0.0])
Q = np.diag([1.0, 1.0, 0.1, 0.1])
QF = np.diag([1e4, 1e4, 1e3, 1e3])
R = np.diag([1e-3, 1e-3])


def build(out: Path):
    if robotgen(["build", str(ROOT / "specs" / "two_link.yaml"), "-o", str(out), "-q"]) != 0:
        raise SystemExit(1)
    sys.path.insert(0, str(out))
    return importlib.import_module("two_link")


def rollout(arm, x0, U):
    X = np.empty((STEPS + 1, 4))
    X[0] = x0
    U = np.clip(U, -LIMIT, LIMIT)
    for k in range(STEPS):
        q, qd = arm.discrete_dynamics(X[k, :2], X[k, 2:], U[k], DT)
        X[k + 1, :2], X[k + 1, 2:] = q, qd
    return X, U


def cost(X, U) -> float:
    e = X - X_GOAL
    running = np.einsum("ki,ij,kj->", e[:-1], Q, e[:-1]) + np.einsum("ki,ij,kj->", U, R, U)
    return float(running * DT + e[-1] @ QF @ e[-1])


def exact_jacobians(arm, X, U):
    """A (N, 4, 4) and B (N, 4, 2) at every knot in one batched call."""
    _, _, A, B = arm.discrete_dynamics_derivatives(X[:-1, :2], X[:-1, 2:], U, DT)
    return A, B


def finite_difference_jacobians(arm, X, U, h=1e-6):
    """The same by central differences of discrete_dynamics: 12 batched calls."""
    Z = np.hstack([X[:-1], U])

    def f(Z):
        q, qd = arm.discrete_dynamics(Z[:, :2], Z[:, 2:4], Z[:, 4:], DT)
        return np.hstack([q, qd])

    columns = [(f(Z + h * e) - f(Z - h * e)) / (2 * h) for e in np.eye(6)]
    J = np.stack(columns, axis=-1)  # (N, 4, 6)
    return J[:, :, :4], J[:, :, 4:]


def ilqr(arm, jacobians, iterations=100, label=""):
    x0 = np.array([-np.pi / 2, 0.0, 0.0, 0.0])
    U = np.zeros((STEPS, 2))
    X, U = rollout(arm, x0, U)
    J = cost(X, U)
    history = [J]
    mu = 1e-6
    start = time.perf_counter()
    in_jacobians = 0.0
    for _ in range(iterations):
        t0 = time.perf_counter()
        A, B = jacobians(arm, X, U)
        in_jacobians += time.perf_counter() - t0
        # backward Riccati sweep on the linearised model (quadratic cost, Gauss-Newton)
        Vx, Vxx = 2 * QF @ (X[-1] - X_GOAL), 2 * QF
        k_ff, K_fb = np.zeros((STEPS, 2)), np.zeros((STEPS, 2, 4))
        for k in reversed(range(STEPS)):
            Qx = 2 * Q @ (X[k] - X_GOAL) * DT + A[k].T @ Vx
            Qu = 2 * R @ U[k] * DT + B[k].T @ Vx
            Qxx = 2 * Q * DT + A[k].T @ Vxx @ A[k]
            Quu = 2 * R * DT + B[k].T @ Vxx @ B[k] + mu * np.eye(2)
            Qux = B[k].T @ Vxx @ A[k]
            k_ff[k] = -np.linalg.solve(Quu, Qu)
            K_fb[k] = -np.linalg.solve(Quu, Qux)
            Vx = Qx + K_fb[k].T @ Quu @ k_ff[k] + K_fb[k].T @ Qu + Qux.T @ k_ff[k]
            Vxx = Qxx + K_fb[k].T @ Quu @ K_fb[k] + K_fb[k].T @ Qux + Qux.T @ K_fb[k]
            Vxx = 0.5 * (Vxx + Vxx.T)
        # forward rollout with a line search
        for alpha in (1.0, 0.5, 0.25, 0.1, 0.03, 0.01):
            Xn = np.empty_like(X)
            Xn[0] = x0
            Un = np.empty_like(U)
            for k in range(STEPS):
                Un[k] = np.clip(U[k] + alpha * k_ff[k] + K_fb[k] @ (Xn[k] - X[k]), -LIMIT, LIMIT)
                q, qd = arm.discrete_dynamics(Xn[k, :2], Xn[k, 2:], Un[k], DT)
                Xn[k + 1, :2], Xn[k + 1, 2:] = q, qd
            Jn = cost(Xn, Un)
            if Jn < J:
                break
        if Jn >= J:
            mu *= 10
            if mu > 1e6:
                break
            continue
        mu = max(mu / 10, 1e-9)
        improvement = J - Jn
        X, U, J = Xn, Un, Jn
        history.append(J)
        if improvement < 1e-7 * J:
            break
    seconds = time.perf_counter() - start
    print(
        f"{label}: cost by iteration: "
        + " ".join(f"{c:.4g}" for c in history[:8])
        + (" ..." if len(history) > 8 else "")
        + f" -> {history[-1]:.6g} after {len(history) - 1} iterations"
    )
    return X, U, history, seconds, in_jacobians


def plot(path: Path, X, U, history_exact, history_fd) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(STEPS + 1) * DT
    fig, axes = plt.subplots(3, 1, figsize=(8, 9))
    for i, name in enumerate(("shoulder", "elbow")):
        axes[0].plot(t, X[:, i], label=name)
    axes[0].axhline(np.pi / 2, color="gray", linestyle="--", linewidth=1, label="shoulder goal (upright)")
    axes[0].set_ylabel("q [rad]")
    axes[0].legend(fontsize=8)
    for i, name in enumerate(("shoulder", "elbow")):
        axes[1].step(t[:-1], U[:, i], where="post", label=name)
    axes[1].axhline(LIMIT, color="gray", linestyle=":", linewidth=1)
    axes[1].axhline(-LIMIT, color="gray", linestyle=":", linewidth=1, label=f"limit +-{LIMIT:g} N m")
    axes[1].set_ylabel("tau [N m]")
    axes[1].set_xlabel("t [s]")
    axes[1].legend(fontsize=8)
    axes[2].semilogy(history_exact, "o-", label="generated derivatives")
    axes[2].semilogy(history_fd, "x--", label="finite differences")
    axes[2].set_xlabel("iLQR iteration")
    axes[2].set_ylabel("cost")
    axes[2].legend(fontsize=8)
    fig.suptitle("two_link swing-up by iLQR")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    print(f"wrote {path}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--plot",
        type=Path,
        default=Path("generated") / "trajectory_optimisation.png",
        help="where to write the plot (default: generated/trajectory_optimisation.png)",
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        arm = build(Path(tmp) / "two_link")
        X, U, h_exact, t_exact, j_exact = ilqr(arm, exact_jacobians, label="generated derivatives")
        _, _, h_fd, t_fd, j_fd = ilqr(arm, finite_difference_jacobians, label="finite differences  ")
        print(f"final state {np.round(X[-1], 4)} (goal {np.round(X_GOAL, 4)}), max |tau| {np.abs(U).max():.1f} N m")
        print(
            f"solve time: generated derivatives {t_exact:.3f} s, finite differences {t_fd:.3f} s "
            f"(ratio {t_fd / t_exact:.2f}; the Python Riccati sweep and rollouts dominate both)"
        )
        print(
            f"of which A, B at all {STEPS} knots: {1e3 * j_exact:.2f} ms vs {1e3 * j_fd:.2f} ms "
            f"(ratio {j_fd / j_exact:.1f})"
        )
        plot(args.plot, X, U, h_exact, h_fd)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
