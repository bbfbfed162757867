"""`robotgen simulate`: close the compiled servo step around the true constrained plant.

The plant is the uncontrolled tree's composite dynamics (Deno et al. 1990, eq 2.3) in the
root's velocity coordinates, integrated by classical RK4 with the leaf joint states carried
along (Theta_dot = A(Theta) v). The servo step runs once per step on the sensed leaf state,
and its torques are held over the step (zero-order hold), as on a real servo loop.
"""
from __future__ import annotations

import csv
import importlib
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robotgen.model.simulation import SimulationSettings as Settings


@dataclass
class Result:
    t: np.ndarray
    x: np.ndarray  # root positions
    x_d: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    names: list[str] = field(default_factory=list)

    @property
    def error(self) -> np.ndarray:
        return self.x - self.x_d


def load_module(out_dir: Path, name: str):
    sys.path.insert(0, str(out_dir))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(out_dir))


def desired(s: Settings, x0: np.ndarray, t: float):
    a = np.zeros_like(x0) if not s.amplitude else np.asarray(s.amplitude, float)
    w = 2 * np.pi * (np.zeros_like(x0) if not s.frequency else np.asarray(s.frequency, float))
    return x0 + a * np.sin(w * t), a * w * np.cos(w * t), -a * w * w * np.sin(w * t)


def run(module, s: Settings) -> Result:
    info = module.info()
    root = info["nodes"][info["root"]]
    n_ext, n_v = len(root["coordinates"]), root["nq"]
    n_fi = len(root["internal_forces"])
    if s.theta0 is not None:
        theta = np.asarray(s.theta0, float)
        x0 = module.plant_position(theta)[:n_ext] if s.start is None else np.asarray(s.start, float)
    else:
        if s.start is None or not hasattr(module, "plant_inverse"):
            raise ValueError("the simulation needs theta0, or start with inverse kinematics in every attach")
        x0 = np.asarray(s.start, float)
        err = np.zeros(n_ext) if not s.initial_error else np.asarray(s.initial_error, float)
        theta = module.plant_inverse(x0 + err)
    _, v_d0, _ = desired(s, x0, 0.0)
    v = np.zeros(module.plant_velocity(theta, np.zeros(module.nq)).shape[0])
    v[:n_ext] = v_d0
    f_i = np.asarray(s.internal_forces, float) if s.internal_forces else np.zeros(n_fi)
    stateful = hasattr(module, "servo_init")

    def theta_dot(th, vel):
        return module.plant_dynamics(th, vel, np.zeros(module.nq))[0]

    state = module.servo_init(theta, theta_dot(theta, v)) if stateful else None
    steps = int(round(s.duration / s.dt))
    T, X, XD, TAU, TH = [], [], [], [], []
    for k in range(steps + 1):
        t = k * s.dt
        x_d, v_d, a_d = desired(s, x0, t)
        args = [theta, theta_dot(theta, v), x_d, _pad(v_d, n_v), _pad(a_d, n_v), np.zeros(n_v)]
        if n_fi:
            args.append(f_i)
        if stateful:
            tau, state = module.servo_step(*args, state, np.array([s.dt]))
        else:
            tau = module.servo_step(*args)
        T.append(t)
        X.append(module.plant_position(theta)[:n_ext])
        XD.append(x_d)
        TAU.append(tau)
        TH.append(theta)
        if k == steps:
            break
        theta, v = _rk4(module, theta, v, tau, s.dt)
        if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(v))):
            raise FloatingPointError(f"the simulation diverged at t = {t:.4f} s")
    return Result(np.array(T), np.array(X), np.array(XD), np.array(TAU), np.array(TH), list(root["coordinates"]))


def _pad(a: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[: a.shape[0]] = a
    return out


def _rk4(module, theta, v, tau, dt):
    def f(th, vel):
        return module.plant_dynamics(th, vel, tau)

    k1 = f(theta, v)
    k2 = f(theta + dt / 2 * k1[0], v + dt / 2 * k1[1])
    k3 = f(theta + dt / 2 * k2[0], v + dt / 2 * k2[1])
    k4 = f(theta + dt * k3[0], v + dt * k3[1])
    return (theta + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
            v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))


def write_csv(result: Result, path: Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        n_tau = result.tau.shape[1]
        w.writerow(["t"] + [f"x_{c}" for c in result.names] + [f"xref_{c}" for c in result.names]
                   + [f"tau_{k + 1}" for k in range(n_tau)])
        for k in range(len(result.t)):
            w.writerow([f"{result.t[k]:.6f}"] + [f"{v:.10g}" for v in result.x[k]]
                       + [f"{v:.10g}" for v in result.x_d[k]] + [f"{v:.10g}" for v in result.tau[k]])


def plot(result: Result, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i, c in enumerate(result.names):
        ax1.semilogy(result.t, np.abs(result.error[:, i]) + 1e-16, label=c)
    ax1.set_ylabel("|x - x_d|")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.grid(True, which="both", alpha=0.3)
    for k in range(result.tau.shape[1]):
        ax2.plot(result.t, result.tau[:, k], label=f"tau {k + 1}")
    ax2.set_ylabel("torque [N m]")
    ax2.set_xlabel("t [s]")
    ax2.legend(loc="upper right", fontsize=8, ncol=2)
    ax2.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summary(result: Result) -> str:
    e = np.linalg.norm(result.error, axis=1)
    lines = [f"simulated {result.t[-1]:.3f} s in {len(result.t) - 1} steps",
             f"tracking error |x - x_d|: start {e[0]:.3e}, max {e.max():.3e}, final {e[-1]:.3e}"]
    for frac in (0.25, 0.5):
        k = int(frac * (len(result.t) - 1))
        lines.append(f"  at t = {result.t[k]:.3f} s: {e[k]:.3e}")
    lines.append(f"max |tau|: {np.abs(result.tau).max():.4g} N m")
    return "\n".join(lines)
