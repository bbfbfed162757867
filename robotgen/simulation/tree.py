"""`robotgen simulate`: close the compiled servo step around the true constrained plant.

The plant is the uncontrolled tree's composite dynamics (Deno et al. 1990, eq 2.3) in the
root's velocity coordinates, integrated by classical RK4 with the leaf joint states carried
along (Theta_dot = A(Theta) v): ``ModulePlant`` (robotgen.simulation.model_plant), with the
spec's wall pushing on it (robotgen.simulation.wall_contact) and its payloads' masses changing
mid-run where the spec says. The
servo step runs once per step on the sensed leaf state (and, when it reads them, the forces
the leaves exert, as a period's end senses them), and its torques are held over the step
(zero-order hold), as on a real servo loop. Another plant with the same methods
(robotgen.simulation.mujoco.run.TreePlant: a MuJoCo model of the same bodies, with contacts) can
take its place.
"""

from __future__ import annotations

import csv
import importlib
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robotgen.model.signature import FORCE_UNITS
from robotgen.model.simulation import RESIDUAL_TOLERANCE, ROBOTGEN_PLANT
from robotgen.model.simulation import SimulationSettings as Settings
from robotgen.simulation.failures import SimulationError, format_values
from robotgen.simulation.model_plant import ModulePlant
from robotgen.simulation.mujoco.contacts import ContactHistory


@dataclass
class Result:
    """A servo simulation: times t [s], root positions x and x_d, torques tau, leaf positions theta, names and units."""

    t: np.ndarray
    x: np.ndarray  # root positions
    x_d: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    names: list[str] = field(default_factory=list)  # root coordinates
    units: list[str] = field(default_factory=list)  # of the root coordinates ('' unknown)
    joints: list[str] = field(default_factory=list)  # leaf joint coordinates, in tau's order
    joint_units: list[str] = field(default_factory=list)
    internal_forces: list[str] = field(default_factory=list)  # every grasp's, as the plant reports
    f_actual: np.ndarray | None = None  # (steps, k) the internal forces the plant carries
    f_commanded: np.ndarray | None = None  # (k,) their commands, NaN where none is known
    plant: str = ROBOTGEN_PLANT  # what the loop was closed around
    contacts: ContactHistory | None = None  # the MuJoCo plant's contacts over the run
    plant_note: str = ""  # how that plant steps
    wall_force: np.ndarray | None = None  # (steps,) the normal force the wall carries, with a wall
    wall_commanded: float = float("nan")  # the force written at the root, along the wall's normal
    changes: tuple = ()  # the payload changes (PayloadChange), in time order

    @property
    def payload_pose(self) -> np.ndarray | None:
        """The true pose of the payload whose coordinates the root's are (MuJoCo's contacts)."""
        pose = getattr(self.contacts, "payload_pose", None)
        return np.array(pose) if pose else None

    @property
    def error(self) -> np.ndarray:
        """The tracking error x - x_d (steps, root coordinates)."""
        return self.x - self.x_d


def load_module(out_dir: Path, name: str):
    """Import the built module ``name`` from out_dir."""
    sys.path.insert(0, str(out_dir))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(out_dir))


def desired(s: Settings, x0: np.ndarray, t: float):
    """(x_d, xd_d, xdd_d) at t [s]: x0 plus the settings' sine, amplitude a and frequency f [Hz] per coordinate."""
    a = np.zeros_like(x0) if not s.amplitude else np.asarray(s.amplitude, float)
    w = 2 * np.pi * (np.zeros_like(x0) if not s.frequency else np.asarray(s.frequency, float))
    return x0 + a * np.sin(w * t), a * w * np.cos(w * t), -a * w * w * np.sin(w * t)


def _start(
    module, s: Settings, rest: Sequence[float] | np.ndarray, n_ext: int
) -> tuple[np.ndarray, np.ndarray, str | None]:
    """(theta at t = 0, x_d(0), the field that chose theta or None for the rest posture)."""
    if s.theta0 is not None:
        theta = np.asarray(s.theta0, float)
        x0 = module.plant_position(theta)[:n_ext] if s.start is None else np.asarray(s.start, float)
        return theta, x0, "theta0"
    if s.start is not None:
        if not hasattr(module, "plant_inverse"):
            raise SimulationError(
                "start needs inverse kinematics in every attach (formulas leaves with "
                "inverse_kinematics, or h_inverse); give theta0 (the leaf joint "
                "positions) instead",
                "start",
            )
        x0 = np.asarray(s.start, float)
        err = np.zeros(n_ext) if not s.initial_error else np.asarray(s.initial_error, float)
        return module.plant_inverse(x0 + err), x0, "start"
    theta = np.asarray(rest, float)
    return theta, module.plant_position(theta)[:n_ext], None


def _check_constraints(module, theta: np.ndarray, source: str | None) -> None:
    info = module.info()
    if not hasattr(module, "constraint_residual"):
        return
    r = module.constraint_residual(theta)
    if not np.all(np.isfinite(r)):
        raise SimulationError(
            "the start posture is outside the reach of the inverse kinematics (the "
            f"constraint residual is {format_values(r)}); give simulation.start inside the "
            "workspace, or theta0",
            source,
        )
    worst = int(np.argmax(np.abs(r)))
    if abs(r[worst]) <= RESIDUAL_TOLERANCE:
        return
    name = info["constraint_residual"][worst]
    attach, coordinate = name.split(".", 1)
    what = {
        "theta0": "theta0 violates",
        "start": "the plant's start (start + initial_error) violates",
        None: "with no simulation section (neither theta0 nor start), the simulation starts at the "
        "joints' mid-range (or zero) posture, which violates",
    }[source]
    advice = "" if source else "; give simulation.start (root positions) or theta0"
    raise SimulationError(
        f"{what} the constraint of attach '{attach}': residual {r[worst]:.3g} in "
        f"'{coordinate}' (y - h^-1(h(y)), largest of {format_values(r)}){advice}",
        source,
    )


def run(
    module, s: Settings, rest: Sequence[float] | np.ndarray | None = None, plant=ModulePlant, multirate: bool = False
) -> Result:
    """The closed loop from the settings; ``rest`` is the leaf posture used when the
    settings give neither theta0 nor start; ``plant(module, theta, theta_dot, v, n_ext)``
    makes the plant it is closed around, given the settings' wall (set_wall) and its payloads'
    masses as they change (set_payload_mass). ``multirate``: the module's MultiRateController
    runs the rate groups at their own periods, one step per s.dt (the fastest period), instead
    of servo_step at s.dt. Raises SimulationError for settings the plant cannot start from and
    for a loop that diverges."""
    info = module.info()
    root = info["nodes"][info["root"]]
    n_ext, n_v = len(root["coordinates"]), root["nq"]
    n_fi = len(root["internal_forces"])
    theta, x0, source = _start(module, s, np.zeros(module.nq) if rest is None else rest, n_ext)
    _check_constraints(module, theta, source)
    _, v_d0, _ = desired(s, x0, 0.0)
    v = np.zeros(module.plant_velocity(theta, np.zeros(module.nq)).shape[0])
    v[:n_ext] = v_d0
    f_i = np.asarray(s.internal_forces, float) if s.internal_forces else np.zeros(n_fi)
    f_e = np.asarray(s.force, float) if s.force else np.zeros(n_v)
    stateful = hasattr(module, "servo_init") and not multirate
    p = plant(module, theta, module.plant_dynamics(theta, v, np.zeros(module.nq))[0], v, n_ext)
    if s.wall is not None:
        p.set_wall(s.wall)
    state = module.servo_init(*p.sensed()) if stateful else None
    controller = module.MultiRateController() if multirate else None
    reads_sensed = hasattr(module, "plant_sensed_forces")  # the servo step takes tau_sensed
    steps = int(round(s.duration / s.dt))
    T, X, XD, TAU, TH, FI, WALL = [], [], [], [], [], [], []
    reads_forces = hasattr(module, "plant_internal_forces")
    tau = np.zeros(module.nq)
    changes = list(s.payload_changes)
    for k in range(steps + 1):
        t = k * s.dt
        while changes and t >= changes[0].at - 1e-9 * s.dt:  # the plant's payload from now on
            change = changes.pop(0)
            p.set_payload_mass(change.payload, change.mass)
        theta, theta_dot = p.sensed()
        x_d, v_d, a_d = desired(s, x0, t)
        args = [theta, theta_dot, x_d, _pad(v_d, n_v), _pad(a_d, n_v), f_e]
        if n_fi:
            args.append(f_i)
        if reads_sensed:
            args.append(p.sensed_forces(tau))
        if controller is not None:
            tau = controller.step(*args)
        elif stateful:
            tau, state = module.servo_step(*args, state, np.array([s.dt]))
        else:
            tau = module.servo_step(*args)
        T.append(t)
        X.append(p.position(theta))
        XD.append(x_d)
        TAU.append(tau)
        TH.append(theta)
        if reads_forces:
            FI.append(p.internal_forces(tau))
        if s.wall is not None:
            WALL.append(p.wall_force())
        p.record(t)
        if k == steps:
            break
        p.step(tau, s.dt, f"at t = {t + s.dt:.4f} s (step {k + 1} of {steps})")
    joints = [c for leaf in info["leaves"] for c in info["nodes"][leaf]["coordinates"]]
    joint_units = [u for leaf in info["leaves"] for u in info["nodes"][leaf]["units"]]
    names = info.get("internal_forces", [])
    commands = dict(zip(root["internal_forces"], f_i))  # left to the root: the simulation's values
    for node in info["nodes"].values():
        commands.update(node.get("internal_force_setpoints", {}))
    on_root = bool(s.force) and s.wall is not None and info["nodes"][s.wall.node]["coordinates"] == root["coordinates"]
    # pushed into the wall
    commanded = float(-f_e[:n_ext] @ np.asarray(s.wall.normal)) if on_root and s.wall is not None else float("nan")
    return Result(
        np.array(T),
        np.array(X),
        np.array(XD),
        np.array(TAU),
        np.array(TH),
        list(root["coordinates"]),
        list(root["units"][:n_ext]),
        joints,
        joint_units,
        names,
        np.array(FI) if reads_forces else None,
        np.array([commands.get(n, np.nan) for n in names]) if reads_forces else None,
        p.name,
        getattr(p, "history", None),
        getattr(p, "note", ""),
        np.array(WALL) if s.wall is not None else None,
        commanded,
        tuple(s.payload_changes),
    )


def _pad(a: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[: a.shape[0]] = a
    return out


def write_csv(result: Result, path: Path) -> None:
    """t, the root coordinates (x_<name>), their reference (xref_<name>), the actuator
    torques by joint (tau_<joint>), the internal forces the grasps carry (f_<name>) and the
    normal force the wall carries (fn_wall); on MuJoCo's contacts also the payload's true pose
    (xtrue_<name>) and per contact its normal force (fn_), tangential force (ft_), cone usage
    |f_t|/(mu f_n) (usage_), slip (slip_) and the tip's distance off its pad (gap_)."""
    fi = result.internal_forces if result.f_actual is not None else []
    c = result.contacts
    pose = result.payload_pose
    contact_keys = ("normal", "tangential", "usage", "slip", "gap")
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        header = (
            ["t"]
            + [f"x_{n}" for n in result.names]
            + [f"xref_{n}" for n in result.names]
            + [f"tau_{j}" for j in result.joints]
            + [f"f_{n}" for n in fi]
        )
        if result.wall_force is not None:
            header.append("fn_wall")
        if pose is not None:
            header += [f"xtrue_{n}" for n in result.names]
        if c is not None:
            header += [f"{key}_{n}" for key in ("fn", "ft", "usage", "slip", "gap") for n in c.names]
        w.writerow(header)
        columns = [c.array(key) for key in contact_keys] if c is not None else []
        for k in range(len(result.t)):
            row = (
                [f"{result.t[k]:.6f}"]
                + [f"{v:.10g}" for v in result.x[k]]
                + [f"{v:.10g}" for v in result.x_d[k]]
                + [f"{v:.10g}" for v in result.tau[k]]
                + [f"{v:.10g}" for v in (result.f_actual[k] if fi and result.f_actual is not None else [])]
            )
            if result.wall_force is not None:
                row.append(f"{result.wall_force[k]:.10g}")
            row += [f"{v:.10g}" for v in (pose[k] if pose is not None else [])]
            row += [f"{v:.10g}" for values in columns for v in values[k]]
            w.writerow(row)


def _unit(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def plot(result: Result, path: Path, title: str) -> None:
    """Per root coordinate: actual and desired trajectory, then the tracking error; the
    actuator torques (forces) by joint; the commanded internal forces, if any. Panels are
    grouped by unit, so metres and radians never share an axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = _by_unit(result.names, result.units)
    force_groups = _by_unit(result.joints, [FORCE_UNITS[u] for u in result.joint_units])
    contacts = result.contacts
    pose = result.payload_pose
    n_rows = (
        2 * len(groups)
        + len(force_groups)
        + (result.f_actual is not None)
        + 2 * (contacts is not None)
        + (result.wall_force is not None)
    )
    fig, grid = plt.subplots(n_rows, 1, figsize=(9, 2.3 * n_rows), sharex=True, squeeze=False)
    axes = list(grid[:, 0])
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for unit, indices in groups.items():
        ax = axes.pop(0)
        for n, i in enumerate(indices):
            c = colors[n % len(colors)]
            ax.plot(result.t, result.x[:, i], color=c, label=f"{result.names[i]}")
            ax.plot(
                result.t, result.x_d[:, i], color=c, linestyle="--", linewidth=1, label=f"{result.names[i]} desired"
            )
        ax.set_ylabel(f"position{_unit(unit)}")
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax.grid(True, alpha=0.3)
        ax = axes.pop(0)
        for n, i in enumerate(indices):
            ax.plot(result.t, result.error[:, i], color=colors[n % len(colors)], label=result.names[i])
            if pose is not None:
                ax.plot(
                    result.t,
                    pose[:, i] - result.x_d[:, i],
                    color=colors[n % len(colors)],
                    linestyle=":",
                    label=f"{result.names[i]}, payload's true pose",
                )
        ax.set_ylabel(f"error x - x_d{_unit(unit)}")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax.grid(True, alpha=0.3)
    for unit, indices in force_groups.items():
        ax = axes.pop(0)
        for n, i in enumerate(indices):
            ax.plot(result.t, result.tau[:, i], color=colors[n % len(colors)], label=result.joints[i])
        label = {"N": "force", "N m": "torque"}.get(unit, "actuator effort")
        ax.set_ylabel(f"{label}{_unit(unit)}")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax.grid(True, alpha=0.3)
    if result.f_actual is not None and result.f_commanded is not None:  # (set together)
        ax = axes.pop(0)
        for n, name in enumerate(result.internal_forces):
            c = colors[n % len(colors)]
            ax.plot(result.t, result.f_actual[:, n], color=c, label=name)
            if np.isfinite(result.f_commanded[n]):
                ax.plot(
                    result.t,
                    np.full_like(result.t, result.f_commanded[n]),
                    color=c,
                    linestyle="--",
                    linewidth=1,
                    label=f"{name} commanded",
                )
        ax.set_ylabel("internal force")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax.grid(True, alpha=0.3)
    if result.wall_force is not None:
        ax = axes.pop(0)
        ax.plot(result.t, result.wall_force, color=colors[0], label="normal force on the wall")
        if np.isfinite(result.wall_commanded):
            ax.plot(
                result.t,
                np.full_like(result.t, result.wall_commanded),
                color=colors[0],
                linestyle="--",
                linewidth=1,
                label="commanded (f_e along the normal)",
            )
        ax.set_ylabel("wall force\nf_n [N]")
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax.grid(True, alpha=0.3)
    for ax in fig.axes:  # the plant's payload changes
        for change in result.changes:
            ax.axvline(change.at, color="k", linestyle=":", linewidth=1)
    if contacts is not None:
        labels = [f"{c.name} ({c.leaf})" for c in contacts.contacts]
        ax = axes.pop(0)
        for n, label in enumerate(labels):
            ax.plot(result.t, contacts.array("normal")[:, n], color=colors[n % len(colors)], label=label)
        ax.set_ylabel("contact normal\nforce f_n [N]")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax.grid(True, alpha=0.3)
        ax = axes.pop(0)
        for n, label in enumerate(labels):
            ax.plot(result.t, contacts.array("usage")[:, n], color=colors[n % len(colors)], label=label)
        ax.axhline(1.0, color="k", linestyle="--", linewidth=1, label="cone limit (sliding)")
        ax.set_ylabel("friction cone use\n|f_t| / (mu f_n)")
        ax.set_ylim(0, 1.1)
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax.grid(True, alpha=0.3)
    fig.axes[-1].set_xlabel("t [s]")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _by_unit(names: list[str], units: list[str]) -> dict[str, list[int]]:
    groups: dict[str, list[int]] = {}
    for i, _ in enumerate(names):
        groups.setdefault(units[i] if i < len(units) else "", []).append(i)
    return groups


def summary(result: Result) -> str:
    """The lines simulate prints: the run, then each root coordinate's largest and final tracking error."""
    lines = [
        f"simulated {result.t[-1]:.3f} s in {len(result.t) - 1} steps on the {result.plant} plant ({result.plant_note})"
        if result.plant_note
        else f"simulated {result.t[-1]:.3f} s in {len(result.t) - 1} steps on the {result.plant} plant",
        "tracking error x - x_d (largest over the run, and at the end):",
    ]
    for i, name in enumerate(result.names):
        unit = result.units[i] if i < len(result.units) else ""
        e = result.error[:, i]
        lines.append(f"  {name:>12}: max {np.abs(e).max():.3e}, final {e[-1]:+.3e}{_unit(unit)}")
    for i, name in enumerate(result.joints):
        unit = FORCE_UNITS[result.joint_units[i]] if i < len(result.joint_units) else ""
        lines.append(f"  {'tau ' + name:>12}: max |.| {np.abs(result.tau[:, i]).max():.4g}{_unit(unit)}")
    return "\n".join(lines + force_lines(result) + contact_lines(result))


def force_lines(result: Result) -> list[str]:
    """The plant's payload changes; each commanded internal force's error (largest over the run,
    and at the end); the wall's normal force (largest, final) and what was commanded into it."""
    lines = []
    if result.changes:
        lines.append(
            "the plant's payload: "
            + ", ".join(f"{c.payload or 'hand'} {c.mass:g} kg from t = {c.at:g} s" for c in result.changes)
        )
    if result.f_actual is not None and result.f_commanded is not None and np.any(np.isfinite(result.f_commanded)):
        lines.append("internal forces f - f_commanded (largest over the run, and at the end):")
        for n, name in enumerate(result.internal_forces):
            if np.isfinite(result.f_commanded[n]):
                e = result.f_actual[:, n] - result.f_commanded[n]
                lines.append(f"  {name:>12}: max {np.abs(e).max():.3e}, final {e[-1]:+.3e}")
    if result.wall_force is not None:
        f = result.wall_force
        line = f"wall: normal force max {f.max():.4g} N, final {f[-1]:.4g} N"
        if np.isfinite(result.wall_commanded):
            line += f" (commanded {result.wall_commanded:.4g} N)"
        lines.append(line)
    return lines


def contact_lines(result: Result) -> list[str]:
    """MuJoCo's contacts over the run and the payload's true pose against x_d, when the plant reports them."""
    if result.contacts is None:
        return []
    lines = list(result.contacts.summary())
    pose = result.payload_pose
    if pose is not None:
        e = pose - result.x_d
        lines.append("the payload's true pose (MuJoCo) against x_d, largest over the run and at the end:")
        for i, name in enumerate(result.names):
            lines.append(
                f"  {name:>12}: max {np.abs(e[:, i]).max():.3e}, final {e[-1, i]:+.3e}"
                f"{_unit(result.units[i] if i < len(result.units) else '')}"
            )
    return lines


def agreement(a: Result, b: Result) -> dict[str, tuple[float, str, float]]:
    """Per unit of the root coordinates: (largest |x_a - x_b| over the run, its coordinate,
    its time)."""
    out: dict[str, tuple[float, str, float]] = {}
    difference = np.abs(a.x - b.x)
    for unit, indices in _by_unit(a.names, a.units).items():
        k, j = np.unravel_index(np.argmax(difference[:, indices]), (difference.shape[0], len(indices)))
        out[unit] = (float(difference[k, indices[j]]), a.names[indices[j]], float(a.t[k]))
    return out


def compare(a: Result, b: Result) -> str:
    """Two plants' runs of one spec side by side: each coordinate's tracking error on both,
    and how closely the two trajectories agree."""
    lines = [
        f"simulated {a.t[-1]:.3f} s in {len(a.t) - 1} steps on both plants:",
        f"  {a.plant}: {a.plant_note}",
        f"  {b.plant}: {b.plant_note}",
        "tracking error x - x_d (largest over the run, and at the end), side by side:",
        f"  {'':>12}  {a.plant:>30}  {b.plant:>30}  {'|x_' + a.plant + ' - x_' + b.plant + '|':>24}",
    ]
    for i, name in enumerate(a.names):
        unit = a.units[i] if i < len(a.units) else ""
        ea, eb = a.error[:, i], b.error[:, i]
        lines.append(
            f"  {name:>12}  max {np.abs(ea).max():.3e}, final {ea[-1]:+.3e}  "
            f"max {np.abs(eb).max():.3e}, final {eb[-1]:+.3e}  "
            f"{np.abs(a.x[:, i] - b.x[:, i]).max():24.3e}{_unit(unit)}"
        )
    for unit, (worst, name, t) in agreement(a, b).items():
        lines.append(
            f"the plants agree to {worst:.3g}{' ' + unit if unit else ''}: the largest |x_{a.plant} - "
            f"x_{b.plant}| over the run ({name} at t = {t:.3f} s)"
        )
    lines.append(f"largest |tau_{a.plant} - tau_{b.plant}|: {np.abs(a.tau - b.tau).max():.3g}")
    for r in (a, b):
        forces = force_lines(r)
        lines += [f"on the {r.plant} plant:"] + ["  " + line for line in forces] if forces else []
    return "\n".join(lines + contact_lines(a) + contact_lines(b))
