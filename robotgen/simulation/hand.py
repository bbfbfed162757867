"""`robotgen simulate` for a hand controller (law resolved_acceleration or resolved_adaptive at
the root): the compiled controller against the chain's true dynamics, the hand following its
start pose plus amplitude sin(2 pi frequency t) on x, y, z, roll, pitch, yaw, and the payload
changing mid-run (the plant's hand picks up point masses the controller is not told about).

The plant is the chain's forward dynamics (the spec's model, and the same with each payload
added to the last link), integrated by RK4 from theta0 with the joint rates of the path's
start (eq 11), or a MuJoCo model of the same chain whose hand holds each payload
(robotgen.simulation.mujoco); the controller runs once per sampling period on the sensed joint
state and its torques are held over the period. An adaptive controller is run three times: adapting,
with its identification frozen (adapt = False), and replaced by resolved acceleration
control with its default gains, so that the plot compares them."""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from robotgen.frontend.control.hand import DEFAULT_KP, DEFAULT_KV
from robotgen.model.chain import with_payload
from robotgen.model.laws import RESOLVED_ACCELERATION
from robotgen.model.laws.hand import HAND_AXES, HAND_DOF, AdaptiveSettings, ResolvedAccelerationSettings
from robotgen.model.simulation import MUJOCO_PLANT, ROBOTGEN_PLANT, SimulationSettings
from robotgen.model.system import RobotSystem
from robotgen.numeric import exact
from robotgen.numeric.rk4 import rk4_step
from robotgen.simulation.failures import DIVERGED, SimulationError
from robotgen.simulation.mujoco.run import Diverged, chain_steps
from robotgen.symbolic.rigid_body.chain import ChainGraphs, Symbols
from robotgen.symbolic.rigid_body.rpy import rpy_of, rpy_rate_map, rpy_rotation
from robotgen.symbolic.root_laws.hand import Hand

# a plant's step: (payload stage, q, qd, tau) -> (q, qd) one period on
PlantStep = Callable[[int, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, ...]]
SETTLE_WINDOW = 1.0  # [s]: the RMS just after a change and at the end of the run


@dataclass
class HandRun:
    """One hand controller's run: hand position p, its position and orientation errors (steps, 3) [m, rad], torques
    (steps, 6) [N m]."""

    key: str  # the CSV's column prefix
    label: str
    p: np.ndarray  # (steps, 3) hand position
    position_error: np.ndarray  # (steps, 3) p - p_d
    orientation_error: np.ndarray  # (steps, 3) the rotation that remains, R_d R^T's vector part
    tau: np.ndarray  # (steps, 6)

    def rms(self, mask: np.ndarray) -> float:
        """RMS of the hand position error's norm over the samples in ``mask`` [m]."""
        e = np.linalg.norm(self.position_error[mask], axis=1)
        return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")

    def largest_torque_step(self, mask: np.ndarray | None = None) -> float:
        """max |tau(k+1) - tau(k)| over joints and the periods ending in ``mask`` [N m]."""
        steps = np.abs(np.diff(self.tau, axis=0)).max(axis=1)
        steps = steps if mask is None else steps[mask[1:]]
        return float(steps.max()) if steps.size else 0.0


@dataclass
class HandResult:
    """A hand simulation: times t [s], desired positions p_d (steps, 3) [m], each controller's run, the payload
    changes, the plant."""

    t: np.ndarray
    p_d: np.ndarray
    joints: list[str]
    runs: list[HandRun] = field(default_factory=list)
    changes: tuple = ()  # PayloadChange, in time order
    plant: str = ROBOTGEN_PLANT
    mjcf: str | None = None  # the MuJoCo plant's model
    plant_note: str = "classical RK4 of the chain's forward dynamics, one step per period"

    def window(self, start: float, length: float = SETTLE_WINDOW) -> np.ndarray:
        """Mask of the samples in [start, start + length) [s]."""
        return (self.t >= start) & (self.t < start + length)

    @property
    def last_window(self) -> np.ndarray:
        """Mask of the last SETTLE_WINDOW seconds."""
        return self.t > self.t[-1] - SETTLE_WINDOW

    @property
    def before(self) -> np.ndarray:
        """Mask of the samples before the first payload change."""
        return self.t < (self.changes[0].at if self.changes else np.inf)


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
        """(pose (4, 4), twist (6,) [m/s, rad/s], its derivative (6,)) of the desired hand path at t [s]."""
        s, c = np.sin(self.w * t), np.cos(self.w * t)
        x = np.r_[self.p0, self.rpy0] + self.a * s
        xd, xdd = self.a * self.w * c, -self.a * self.w**2 * s
        R, omega, domega = (np.array(v) for v in self._angular(x[3:], xd[3:], xdd[3:]))
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = R, x[:3]
        return pose, np.r_[xd[:3], omega.ravel()], np.r_[xdd[:3], domega.ravel()]


def chain_rk4(tree, T: float) -> ca.Function:
    """(q, qd, tau) -> (q, qd) one period T later, tau held: RK4 on the chain's forward dynamics."""
    sym = Symbols.make(tree.nq)
    f = ca.Function("fd", [sym.q, sym.qd, sym.tau], [ChainGraphs(tree, sym).forward_dynamics()])
    q, qd, tau = sym.q, sym.qd, sym.tau
    return ca.Function("rk4", [q, qd, tau], list(rk4_step(lambda x, v: (v, f(x, v, tau)), q, qd, T)))


def refusal(system: RobotSystem) -> str | None:
    """Why ``robotgen simulate`` cannot run this hand controller: never (a law's simulation
    answers this, robotgen.model.laws.registry)."""
    return None


def comparison_system(system: RobotSystem) -> RobotSystem | None:
    """An adaptive controller's spec with resolved acceleration control at its root instead,
    with the same period and hand and that law's default gains: the reference its simulation
    compares against (None for resolved acceleration control itself)."""
    node = system.root_control
    if not isinstance(node.hand, AdaptiveSettings):
        return None
    hand = ResolvedAccelerationSettings(
        node.hand.period, node.hand.tool, np.full(HAND_DOF, DEFAULT_KP), np.full(HAND_DOF, DEFAULT_KV)
    )
    root = dataclasses.replace(node, law=RESOLVED_ACCELERATION, hand=hand)
    return dataclasses.replace(system, name=f"{system.name}_rac", nodes={**system.nodes, system.root: root})


def simulate(
    module, system: RobotSystem, s: SimulationSettings, plant: str, comparison=None
) -> tuple[HandResult, str | None]:
    """Every run against ``plant`` (``comparison``: the module of comparison_system, if any),
    and the MuJoCo plant's MJCF or None: the laws' simulation entry (robotgen.model.laws.registry)."""
    result = run(module, system, s, comparison, plant=plant)
    return result, result.mjcf


def run(
    module,
    system: RobotSystem,
    s: SimulationSettings,
    comparison=None,
    keys: tuple[str, ...] | None = None,
    plant: str = ROBOTGEN_PLANT,
) -> HandResult:
    """Every run of the spec's controller (``comparison``: the module of comparison_system,
    run too when the controller is adaptive), or those of ``keys`` (adaptive, frozen, rac),
    against ``plant`` (robotgen or mujoco)."""
    node = system.root_control
    tree = system.tree(node.robot)
    hand = Hand(tree, node.hand_settings.tool)
    q_sym = hand.sym.q
    R_sym, p_sym = hand.pose(q_sym)
    pose_f = ca.Function("pose", [q_sym], [R_sym, p_sym, rpy_of(R_sym)])
    rates_f = ca.Function("rates", [q_sym, hand.sym.qd], [hand.joint_rates(q_sym, hand.sym.qd)])
    q0 = np.asarray(s.theta0 if s.theta0 is not None else np.zeros(tree.nq), float)
    hand_frame = exact.matmul(tree.tool, node.hand_settings.tool)  # the hand in the last joint's frame
    period = node.hand_settings.period
    mjcf = note = None
    step: PlantStep
    if plant == MUJOCO_PLANT:
        stages = [(0.0, np.zeros(3))] + [(c.mass, np.asarray(c.com, float)) for c in s.payload_changes]
        model, chain_step = chain_steps(system, module, period, q0, hand_frame, stages)
        mjcf, note, step = model.xml, chain_step.sim.note, chain_step
    else:
        plants = [chain_rk4(tree, period)]
        for change in s.payload_changes:
            point = hand_frame[:3, 3] + hand_frame[:3, :3] @ np.asarray(change.com, float)
            plants.append(chain_rk4(with_payload(tree, change.mass, point), period))

        def rk4_plant(stage: int, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, ...]:
            with np.errstate(all="ignore"):
                return tuple(np.array(v).ravel() for v in plants[stage](q, qd, tau))

        step = rk4_plant
    _, p0, rpy0 = (np.array(v) for v in pose_f(q0))
    trajectory = Trajectory(p0.ravel(), rpy0.ravel(), s.amplitude, s.frequency)
    steps = int(round(s.duration / period))
    t = np.arange(steps + 1) * period
    p_d = np.array([trajectory.at(tk)[0][:3, 3] for tk in t])
    result = HandResult(t, p_d, [j.name for j in tree.joints], changes=s.payload_changes, plant=plant, mjcf=mjcf)
    if note:
        result.plant_note = note
    if isinstance(node.hand, AdaptiveSettings):
        setups: list[tuple[str, str, type, bool | None]] = [
            ("adaptive", "adaptive", module.AdaptiveController, True),
            ("frozen", "identification frozen (adapt = False)", module.AdaptiveController, False),
        ]
        if comparison is not None:
            setups.append(
                (
                    "rac",
                    f"resolved acceleration (Kp = {DEFAULT_KP:g}, Kv = {DEFAULT_KV:g})",
                    comparison.ResolvedAccelerationController,
                    None,
                )
            )
    else:
        setups = [("rac", node.law.replace("_", " "), module.ResolvedAccelerationController, None)]
    switch = np.searchsorted([c.at for c in s.payload_changes], t, side="right")  # the plant at each t
    qd0 = np.array(rates_f(q0, trajectory.at(0.0)[1])).ravel()  # the plant starts on the path (eq 11)
    for key, label, cls, adapt in setups:
        if keys is not None and key not in keys:
            continue
        controller = cls()
        if adapt is not None:
            controller.adapt = adapt
        result.runs.append(_closed_loop(controller, trajectory, step, switch, pose_f, q0, qd0, t, key, label))
    return result


def _closed_loop(controller, trajectory: Trajectory, step, switch, pose_f, q0, qd0, t, key, label) -> HandRun:
    """One run: ``step(stage, q, qd, tau) -> (q, qd)`` one period on, the plant holding the
    payload of ``stage``; ``switch[k]`` the stage of period k."""
    q, qd = q0.copy(), qd0.copy()
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
        try:
            q, qd = step(switch[k], q, qd, tau)
        except Diverged:
            q = np.full_like(q, np.nan)
        if not (np.all(np.abs(q) < DIVERGED) and np.all(np.abs(qd) < DIVERGED)):
            raise SimulationError(
                f"the {label} loop diverged at t = {t[k + 1]:.4f} s (q = {np.round(q, 4)}); "
                "lower the controller's gains or weights"
            )
    return HandRun(key, label, np.array(P), np.array(EP), np.array(EO), np.array(TAU))


def write_csv(result: HandResult, path: Path) -> None:
    """t, the desired hand position, then per run (adaptive, frozen, rac; or rac) its hand
    position error (x, y, z) [m], orientation error [rad] and joint torques."""
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
    """Hand position error over time for every run on one log axis (the payload changes
    marked), every run's largest torque step per period, and the first run's torques."""
    import matplotlib  # deferred: plotting only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 9.5), sharex=True)
    ax = axes[0]
    for r in result.runs:
        ax.semilogy(result.t, np.maximum(1e3 * np.linalg.norm(r.position_error, axis=1), 1e-6), label=r.label)
    for change in result.changes:
        for a in axes:
            a.axvline(change.at, color="k", linestyle=":", linewidth=1)
        ax.annotate(f" {change.mass:g} kg", (change.at, 0.04), xycoords=("data", "axes fraction"), fontsize=8)
    ax.set_ylabel("hand position error\n|p - p_d| [mm]")
    ax.set_ylim(bottom=max(ax.get_ylim()[0], 1e-5))
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, fontsize=8, frameon=False)
    ax.grid(True, which="both", alpha=0.3)
    ax = axes[1]
    for r in result.runs:
        ax.plot(result.t[1:], np.abs(np.diff(r.tau, axis=0)).max(axis=1), label=r.label, linewidth=1)
    ax.set_ylabel("largest torque step\nper period [N m]")
    ax.grid(True, alpha=0.3)
    ax = axes[2]
    first = result.runs[0]
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


def _windows(result: HandResult) -> tuple[list[str], list[np.ndarray]]:
    """The RMS windows: before the first change (or the whole run), the first second after
    each change, the last second."""
    columns = ["before"] if result.changes else ["whole run"]
    columns += [f"{change.at:g}-{change.at + SETTLE_WINDOW:g} s" for change in result.changes] + ["last second"]
    windows = [result.before if result.changes else np.ones_like(result.t, bool)]
    windows += [result.window(change.at) for change in result.changes] + [result.last_window]
    return columns, windows


def _header(result: HandResult) -> list[str]:
    lines = []
    for change in result.changes:
        com = (
            ""
            if not any(change.com)
            else f", centre of mass ({', '.join(f'{v:g}' for v in change.com)}) m in the hand frame"
        )
        lines.append(f"payload {change.mass:g} kg at the hand from t = {change.at:g} s{com}")
    return lines


def summary(result: HandResult) -> str:
    """Per run: the RMS hand position error before the first change, over the first second
    after each change and over the last second, and the largest torque step per period."""
    lines = [
        f"simulated {result.t[-1]:.3f} s in {len(result.t) - 1} periods on the {result.plant} plant "
        f"({result.plant_note})"
    ] + _header(result)
    columns, windows = _windows(result)
    lines.append("RMS hand position error [mm], and the largest torque step per period [N m]:")
    lines.append(f"  {'':40} " + " ".join(f"{c:>12}" for c in columns) + f" {'max |dtau|':>11}")
    for r in result.runs:
        lines.append(
            f"  {r.label:>40} "
            + " ".join(f"{1e3 * r.rms(m):12.4f}" for m in windows)
            + f" {r.largest_torque_step():11.2f}"
        )
    return "\n".join(lines)


def compare(a: HandResult, b: HandResult) -> str:
    """Both plants' runs side by side, and how closely the hand paths agree."""
    lines = [
        f"simulated {a.t[-1]:.3f} s in {len(a.t) - 1} periods on both plants:",
        f"  {a.plant}: {a.plant_note}",
        f"  {b.plant}: {b.plant_note}",
    ] + _header(a)
    columns, windows = _windows(a)
    lines.append("RMS hand position error [mm], and the largest torque step per period [N m]:")
    lines.append(f"  {'':40} {'plant':>9} " + " ".join(f"{c:>12}" for c in columns) + f" {'max |dtau|':>11}")
    for ra, rb in zip(a.runs, b.runs):
        for plant, r in ((a.plant, ra), (b.plant, rb)):
            lines.append(
                f"  {r.label:>40} {plant:>9} "
                + " ".join(f"{1e3 * r.rms(m):12.4f}" for m in windows)
                + f" {r.largest_torque_step():11.2f}"
            )
    worst = [
        (ra.label, float(np.abs(ra.p - rb.p).max()), float(np.abs(ra.tau - rb.tau).max()))
        for ra, rb in zip(a.runs, b.runs)
    ]
    lines.append(
        f"the plants agree: largest |p_{a.plant} - p_{b.plant}| over the run (hand position), and "
        f"|tau_{a.plant} - tau_{b.plant}|:"
    )
    lines += [f"  {label:>40} {dp:.3g} m, {dtau:.3g} N m" for label, dp, dtau in worst]
    return "\n".join(lines)
