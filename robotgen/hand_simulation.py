"""`robotgen simulate` for a hand controller (law resolved_acceleration or resolved_adaptive at
the root): the compiled controller against the chain's true dynamics, the hand following its
start pose plus amplitude sin(2 pi frequency t) on x, y, z, roll, pitch, yaw, and the payload
changing mid-run (the plant's hand picks up a point mass the controller is not told about).

The plant is the chain's forward dynamics (the spec's model, and the same with the payload
added to the last link at the hand), integrated by RK4 from theta0 with the joint rates of
the path's start (eq 11); the controller runs once per sampling period on the sensed joint
state and its torques are held over the period. An adaptive controller is run twice, adapting
and with its identification frozen (adapt = False), so that the plot compares them."""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from robotgen.model.chain import with_payload
from robotgen.model.laws import RESOLVED_ADAPTIVE
from robotgen.model.laws.hand import HAND_AXES
from robotgen.model.simulation import SimulationSettings
from robotgen.model.system import RobotSystem
from robotgen.numeric import exact
from robotgen.simulate import DIVERGED, SimulationError
from robotgen.symbolic.control.hand import Hand
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rate_map, rpy_rotation


@dataclass
class HandRun:
    key: str  # the CSV's column prefix
    label: str
    p: np.ndarray  # (steps, 3) hand position
    position_error: np.ndarray  # (steps, 3) p - p_d
    orientation_error: np.ndarray  # (steps, 3) the rotation that remains, R_d R^T's vector part
    tau: np.ndarray  # (steps, 6)

    def rms(self, mask: np.ndarray) -> float:
        """RMS of the hand position error's norm over the samples in ``mask`` [m]."""
        e = np.linalg.norm(self.position_error[mask], axis=1)
        return float(np.sqrt(np.mean(e ** 2))) if e.size else float("nan")


@dataclass
class HandResult:
    t: np.ndarray
    p_d: np.ndarray
    joints: list[str]
    runs: list[HandRun] = field(default_factory=list)
    change: float | None = None  # when the payload changed [s]
    mass: float = 0.0


class Trajectory:
    """The desired hand trajectory: start pose plus amplitude sin(2 pi frequency t) on the
    position and on roll, pitch, yaw; twist [v; omega] and its derivative in base axes."""

    def __init__(self, p0: np.ndarray, rpy0: np.ndarray, amplitude, frequency):
        self.p0, self.rpy0 = p0, rpy0
        self.a = np.asarray(amplitude, float) if len(amplitude) else np.zeros(6)
        self.w = 2 * np.pi * (np.asarray(frequency, float) if len(frequency) else np.zeros(6))
        phi, dphi, ddphi = (ca.SX.sym(s, 3) for s in ("phi", "dphi", "ddphi"))
        E = rpy_rate_map(phi)
        omega = E @ dphi
        domega = ca.jtimes(omega, phi, dphi) + E @ ddphi
        self._angular = ca.Function("angular", [phi, dphi, ddphi], [rpy_rotation(phi), omega, domega])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, c = np.sin(self.w * t), np.cos(self.w * t)
        x = np.r_[self.p0, self.rpy0] + self.a * s
        xd, xdd = self.a * self.w * c, -self.a * self.w ** 2 * s
        R, omega, domega = (np.array(v) for v in self._angular(x[3:], xd[3:], xdd[3:]))
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = R, x[:3]
        return pose, np.r_[xd[:3], omega.ravel()], np.r_[xdd[:3], domega.ravel()]


def _forward_dynamics(tree) -> ca.Function:
    sym = Symbols.make(tree.nq)
    return ca.Function("fd", [sym.q, sym.qd, sym.tau], [ChainGraphs(tree, sym).forward_dynamics()])


def run(module, system: RobotSystem, s: SimulationSettings) -> HandResult:
    node = system.root_node
    tree = system.nodes[node.robot].leaf
    hand = Hand(tree, node.hand.tool)
    q_sym = hand.sym.q
    R_sym, p_sym = hand.pose(q_sym)
    pose_f = ca.Function("pose", [q_sym], [R_sym, p_sym, rpy_of(R_sym)])
    rates_f = ca.Function("rates", [q_sym, hand.sym.qd], [hand.joint_rates(q_sym, hand.sym.qd)])
    q0 = np.asarray(s.theta0 if s.theta0 is not None else np.zeros(tree.nq), float)
    hand_point = exact.matmul(tree.tool, node.hand.tool)[:3, 3]  # the hand origin in the last joint's frame
    change = s.payload_change
    plants = (_forward_dynamics(tree),
              _forward_dynamics(with_payload(tree, change.mass, hand_point)) if change else None)
    _, p0, rpy0 = (np.array(v) for v in pose_f(q0))
    trajectory = Trajectory(p0.ravel(), rpy0.ravel(), s.amplitude, s.frequency)
    period = node.hand.period
    steps = int(round(s.duration / period))
    t = np.arange(steps + 1) * period
    p_d = np.array([trajectory.at(tk)[0][:3, 3] for tk in t])
    cls = getattr(module, "AdaptiveController" if node.law == RESOLVED_ADAPTIVE else "ResolvedAccelerationController")
    setups = [("adaptive", "adaptive", True), ("frozen", "identification frozen (adapt = False)", False)] \
        if node.law == RESOLVED_ADAPTIVE else [("rac", node.law.replace("_", " "), None)]
    result = HandResult(t, p_d, [j.name for j in tree.joints], change=change.at if change else None,
                        mass=change.mass if change else 0.0)
    for key, label, adapt in setups:
        controller = cls()
        if adapt is not None:
            controller.adapt = adapt
        qd0 = np.array(rates_f(q0, trajectory.at(0.0)[1])).ravel()  # the plant starts on the path (eq 11)
        result.runs.append(_closed_loop(controller, trajectory, plants, change, pose_f, q0, qd0, t, key, label))
    return result


def _closed_loop(controller, trajectory: Trajectory, plants, change, pose_f, q0, qd0, t, key, label) -> HandRun:
    q, qd = q0.copy(), qd0.copy()
    T = t[1] - t[0] if len(t) > 1 else 1e-3
    P, EP, EO, TAU = [], [], [], []
    for k, tk in enumerate(t):
        pose_d, twist_d, accel_d = trajectory.at(tk)
        tau = np.asarray(controller.step(q, qd, pose_d, twist_d, accel_d), float)
        R, p, _ = (np.array(v) for v in pose_f(q))
        p = p.ravel()
        E = pose_d[:3, :3] @ R.T
        P.append(p)
        EP.append(p - pose_d[:3, 3])
        EO.append(0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]))
        TAU.append(tau)
        if k == len(t) - 1:
            break
        plant = plants[1] if change is not None and tk >= change.at else plants[0]
        q, qd = _rk4(plant, q, qd, tau, T)
        if not (np.all(np.abs(q) < DIVERGED) and np.all(np.abs(qd) < DIVERGED)):
            raise SimulationError(f"the {label} loop diverged at t = {tk + T:.4f} s (q = {np.round(q, 4)}); "
                                  "lower the controller's gains or weights")
    return HandRun(key, label, np.array(P), np.array(EP), np.array(EO), np.array(TAU))


def _rk4(f: ca.Function, q, qd, tau, T):
    def rates(q, qd):
        return qd, np.array(f(q, qd, tau)).ravel()

    with np.errstate(all="ignore"):
        k1 = rates(q, qd)
        k2 = rates(q + T / 2 * k1[0], qd + T / 2 * k1[1])
        k3 = rates(q + T / 2 * k2[0], qd + T / 2 * k2[1])
        k4 = rates(q + T * k3[0], qd + T * k3[1])
        return (q + T / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
                qd + T / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))


def write_csv(result: HandResult, path: Path) -> None:
    """t, the desired hand position, then per run (adaptive, frozen; or rac) its hand position
    error (x, y, z) [m], orientation error [rad] and joint torques."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        header = ["t"] + [f"xd_{a}" for a in HAND_AXES[:3]]
        for r in result.runs:
            tag = r.key
            header += [f"{tag}_e_{a}" for a in HAND_AXES[:3]] + [f"{tag}_e_r{a}" for a in "xyz"]
            header += [f"{tag}_tau_{j}" for j in result.joints]
        w.writerow(header)
        for k in range(len(result.t)):
            row = [f"{result.t[k]:.6f}"] + [f"{v:.10g}" for v in result.p_d[k]]
            for r in result.runs:
                row += [f"{v:.10g}" for v in (*r.position_error[k], *r.orientation_error[k], *r.tau[k])]
            w.writerow(row)


def plot(result: HandResult, path: Path, title: str) -> None:
    """Hand position error over time for every run on one axis (the payload change marked),
    the hand path per axis, and the first run's torques."""
    import matplotlib  # deferred: plotting only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    ax = axes[0]
    for r in result.runs:
        ax.plot(result.t, 1e3 * np.linalg.norm(r.position_error, axis=1), label=r.label)
    if result.change is not None:
        ax.axvline(result.change, color="k", linestyle=":", linewidth=1)
        ax.annotate(f" payload +{result.mass:g} kg", (result.change, ax.get_ylim()[1] * 0.9), fontsize=8)
    ax.set_ylabel("hand position error\n|p - p_d| [mm]")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax = axes[1]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    first = result.runs[0]
    for i, a in enumerate(HAND_AXES[:3]):
        ax.plot(result.t, first.p[:, i], color=colors[i], label=f"{a} ({first.label})")
        ax.plot(result.t, result.p_d[:, i], color=colors[i], linestyle="--", linewidth=1, label=f"{a} desired")
    ax.set_ylabel("hand position [m]")
    ax.legend(loc="upper right", fontsize=7, ncol=3)
    ax.grid(True, alpha=0.3)
    ax = axes[2]
    for j, name in enumerate(result.joints):
        ax.plot(result.t, first.tau[:, j], label=name)
    ax.set_ylabel(f"torque [N m]\n({first.label})")
    ax.set_xlabel("t [s]")
    ax.legend(loc="upper right", fontsize=7, ncol=3)
    ax.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summary(result: HandResult) -> str:
    before = result.t < (result.change if result.change is not None else np.inf)
    lines = [f"simulated {result.t[-1]:.3f} s in {len(result.t) - 1} periods"]
    if result.change is not None:
        lines.append(f"payload +{result.mass:g} kg at the hand at t = {result.change:g} s")
    lines.append("RMS hand position error [m]:" + ("   before the change   after it" if result.change is not None
                                                   else ""))
    for r in result.runs:
        if result.change is not None:
            lines.append(f"  {r.label:>40}: {r.rms(before):.3e}   {r.rms(~before):.3e}")
        else:
            lines.append(f"  {r.label:>40}: {r.rms(np.ones_like(before)):.3e}")
    return "\n".join(lines)
