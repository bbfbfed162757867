"""robotgen's main job on an example: build the PUMA 560 spec, import the generated module,
and close a computed-torque loop around the arm's own forward dynamics.

    python examples/demo.py [SPEC.yaml]

The plant is the generated `forward_dynamics` integrated by RK4 at 1 kHz; the controller
is computed torque, tau = M(q) (qdd_d + Kv (qd_d - qd) + Kp (q_d - q)) + C(q, qd) qd + N(q, qd),
from the generated `mass` and `nonlinear`. With exact models the error obeys
e'' + Kv e' + Kp e = 0, so it decays at the rate the gains set; the demo prints it.
"""
from __future__ import annotations

import importlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from robotgen.cli import main as robotgen  # noqa: E402


def build(spec: Path, out: Path):
    if robotgen(["build", str(spec), "-o", str(out)]) != 0:
        raise SystemExit(1)
    sys.path.insert(0, str(out))
    name = next(out.glob("*.h")).stem
    return importlib.import_module(name)


def desired(t: float, q0: np.ndarray):
    """A smooth joint trajectory: q0 + 0.3 sin(w t) on every joint."""
    w, ones = 2.0, np.ones_like(q0)
    return q0 + 0.3 * np.sin(w * t), 0.3 * w * np.cos(w * t) * ones, -0.3 * w * w * np.sin(w * t) * ones


def main() -> None:
    spec = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "specs" / "puma560.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        arm = build(spec, Path(tmp) / "out")
        n = arm.nq
        print(f"built {spec.name}: module '{arm.__name__}', nq = {n}, functions: "
              f"{', '.join(arm.info()['functions'])}")
        wn = 20.0  # closed-loop natural frequency [rad/s], critically damped
        Kp, Kv = wn * wn, 2 * wn
        dt, T = 1e-3, 2.0
        q0 = np.array([0.0, np.pi / 4, np.pi, 0.0, np.pi / 4, 0.0])[:n]
        q, qd = q0 + 0.05, desired(0.0, q0)[1]  # start 0.05 rad off the trajectory

        def control(t, q, qd):
            q_d, qd_d, qdd_d = desired(t, q0)
            a = qdd_d + Kv * (qd_d - qd) + Kp * (q_d - q)
            return arm.mass(q) @ a + arm.nonlinear(q, qd)

        def f(q, qd, tau):
            return qd, arm.forward_dynamics(q, qd, tau)

        steps = int(T / dt)
        t_ctrl = 0.0
        print(f"closed loop: computed torque, Kp = {Kp:g}, Kv = {Kv:g}, RK4 at {1/dt:g} Hz for {T:g} s")
        print(f"{'t [s]':>6} {'|e| [rad]':>12} {'predicted':>12} {'|tau| [Nm]':>11}")
        e0 = np.linalg.norm(q - q0)
        for k in range(steps + 1):
            t = k * dt
            c0 = time.perf_counter()
            tau = control(t, q, qd)
            t_ctrl += time.perf_counter() - c0
            if k % 250 == 0:
                e = np.linalg.norm(q - desired(t, q0)[0])
                print(f"{t:6.2f} {e:12.3e} {e0 * (1 + wn * t) * np.exp(-wn * t):12.3e} {np.linalg.norm(tau):11.2f}")
            if k == steps:
                break
            k1q, k1v = f(q, qd, tau)
            k2q, k2v = f(q + dt / 2 * k1q, qd + dt / 2 * k1v, tau)
            k3q, k3v = f(q + dt / 2 * k2q, qd + dt / 2 * k2v, tau)
            k4q, k4v = f(q + dt * k3q, qd + dt * k3v, tau)
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            qd = qd + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        print("(the measured error levels off near 1e-5 rad: tau is held constant over each 1 ms "
              "step, as a servo loop holds it; the prediction is for a continuous controller)")
        print(f"tip position at the end: {np.round(arm.fk(q)[:3, 3], 4)} m")
        print(f"controller (M, C qd + N from the module, plus numpy): {t_ctrl / (steps + 1) * 1e6:.1f} us per step")


if __name__ == "__main__":
    main()
