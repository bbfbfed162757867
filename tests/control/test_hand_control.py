"""Resolved motion adaptive control closes the loop on the full nonlinear PUMA 560 (Lee and
Lee 1983) for 10 s: the compiled AdaptiveController tracks a Cartesian path while the plant's
hand picks up 2 kg, 5 kg, or 5 kg off the wrist axis mid-run. After the change its hand
error settles (the last second's RMS is at most the first second's after the change, and
small), below the same controller's with its identification frozen and below resolved
acceleration control with its default gains, and its torque changes per period are what the
plant demands. `robotgen simulate` shows the same comparison."""

from __future__ import annotations

import csv
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from robotgen.frontend import load_system
from robotgen.model.simulation import PayloadChange
from robotgen.simulation.hand import run

ROOT = Path(__file__).resolve().parents[2]
RMAC = ROOT / "specs" / "puma560_rmac.yaml"
G = 9.81


def rac_spec(tmp_path: Path) -> Path:
    """The same arm, hand, path and payload change under resolved acceleration control with
    its default gains (Kp = 400, Kv = 40: critically damped at 20 rad/s for the nominal arm)."""
    data = yaml.safe_load(RMAC.read_text())
    control = data["nodes"]["rmac"]["control"]
    control["law"] = "resolved_acceleration"
    control["resolved_acceleration"] = {
        "period": control["resolved_adaptive"]["period"],
        "tool": control.pop("resolved_adaptive")["tool"],
    }
    data["name"] = "puma560_rac_nominal"  # another module than test_emit_controllers' puma560_rac
    path = tmp_path / "puma560_rac_nominal.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def loops(build_module, tmp_path_factory):
    rmac = load_system(str(RMAC))
    rac_path = rac_spec(tmp_path_factory.mktemp("hand_control"))
    return rmac, build_module(RMAC), build_module(rac_path)


@pytest.mark.parametrize(
    "change",
    [PayloadChange(1.0, 2.0), PayloadChange(1.0, 5.0), PayloadChange(1.0, 5.0, (0.05, 0.05, 0.03))],
    ids=["2kg", "5kg", "5kg_off_axis"],
)
def test_adaptive_control_settles_after_a_payload_step(loops, change):
    system, module, rac_module = loops
    settings = dataclasses.replace(system.simulation, duration=10.0, payload_changes=(change,))
    result = run(module, system, settings, rac_module)
    runs = {r.key: r for r in result.runs}
    first, last = result.window(change.at), result.last_window
    print(
        f"\n  PUMA 560, {change.mass:g} kg at {change.com} in the hand frame from t = {change.at:g} s; "
        "RMS hand position error [mm] before, 1 s after, last second; max |dtau| [N m]:"
    )
    for key, r in runs.items():
        print(
            f"    {key:9s} {1e3 * r.rms(result.before):8.4f} {1e3 * r.rms(first):8.4f} {1e3 * r.rms(last):8.4f} "
            f"{r.largest_torque_step():7.2f}"
        )
    adaptive = runs["adaptive"]
    assert adaptive.rms(last) <= adaptive.rms(first)  # settles, does not drift
    assert np.linalg.norm(adaptive.position_error[last], axis=1).max() < 1e-4  # below 0.1 mm at the end
    assert adaptive.rms(last) < runs["frozen"].rms(last) / 5
    assert adaptive.rms(last) < runs["rac"].rms(last) / 100
    assert adaptive.rms(result.before) < 1e-5 and runs["frozen"].rms(result.before) < 1e-5  # nominal: both track
    assert runs["frozen"].rms(last) > 10 * runs["frozen"].rms(result.before)  # the payload does disturb the loop
    # torque steps: outside the change no larger than resolved acceleration control's (no
    # identification) by more than half; at the change at most the payload's weight times its reach
    step = (result.t >= change.at) & (result.t < change.at + 0.05)
    assert adaptive.largest_torque_step(~step) <= 1.5 * runs["rac"].largest_torque_step(~step)
    reach = np.linalg.norm(adaptive.p[0]) + np.linalg.norm(change.com)
    assert adaptive.largest_torque_step(step) <= change.mass * G * reach


def test_weight_rule_gives_the_bandwidth(loops):
    """The closed loop of the one-step control at the start pose (robotgen info's figure): the
    rule's Q and R put its poles inside the unit circle with time constants of at most 0.1 s:
    six near (2 - bandwidth T) / (2 + bandwidth T) (positions and orientations), six within a
    few periods (the rates); the first defaults of this law (Q = diag(1e6, 1e6, 1e4, 1e4),
    R = 1e-5) left six poles at 0.9999 or above."""
    from robotgen.symbolic.root_laws.resolved_adaptive import closed_loop

    system, _, _ = loops
    s = system.root_node.hand
    loop = closed_loop(system)
    print(f"\n  closed loop at theta0: radius {loop['spectral_radius']}, time constant {loop['time_constant']} s")
    assert loop["spectral_radius"] < 1 and loop["time_constant"] <= 0.1
    T, sigma = s.period, s.bandwidth
    fast = [m for m in loop["moduli"] if m < 0.6]
    slow = [m for m in loop["moduli"] if m >= 0.6]
    assert len(fast) == 6 and len(slow) == 6
    assert all(abs(m - (2 - sigma * T) / (2 + sigma * T)) < 0.01 for m in slow)
    old = dataclasses.replace(s, q=np.repeat([1e6, 1e6, 1e4, 1e4], 3), r=np.full(6, 1e-5))
    old_system = dataclasses.replace(
        system, nodes={**system.nodes, system.root: dataclasses.replace(system.root_node, hand=old)}
    )
    first_defaults = closed_loop(old_system)  # moduli to 4 digits
    assert sorted(first_defaults["moduli"])[-6] >= 0.9999


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """`robotgen simulate` of the adaptive PUMA, the spec's full 10 s: (its output directory, what it printed)."""
    out = tmp_path_factory.mktemp("rmac_simulation")
    sim = subprocess.run(
        [sys.executable, "-m", "robotgen", "simulate", str(RMAC), "-q", "-o", str(out)],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert sim.returncode == 0, sim.stderr
    return out, sim.stdout


def test_simulate_writes_the_comparison(simulated):
    out, printed = simulated
    for label in ("adaptive", "identification frozen (adapt = False)", "resolved acceleration (Kp = 400, Kv = 40)"):
        assert f"  {label} " in printed
    with open(out / "puma560_rmac.csv", newline="") as f:
        table = list(csv.reader(f))
    header = table[0]
    assert header[:4] == ["t", "xd_x", "xd_y", "xd_z"]
    assert "adaptive_e_x" in header and "frozen_e_x" in header and "rac_e_x" in header and "adaptive_tau_q1" in header
    rows = np.array(table[1:], dtype=float)
    assert rows.shape[0] == 10001  # 10 s at the controller's 1 ms period, both ends
    png = (out / "puma560_rmac.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    bad = subprocess.run(
        [sys.executable, "-m", "robotgen", "simulate", str(RMAC), "-o", str(out), "--dt", "0.01"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert bad.returncode == 2 and "runs at its own period" in bad.stderr


def test_readme_quotes_what_simulate_and_info_print(simulated):
    """The README's figures for the adaptive PUMA are the ones `robotgen simulate` (the full
    10 s of the spec) and `robotgen info` print now."""
    readme = " ".join((ROOT / "README.md").read_text().split())
    _, printed = simulated
    last = {}
    for line in printed.splitlines():
        for key, label in (
            ("adaptive", "adaptive"),
            ("frozen", "identification frozen"),
            ("rac", "resolved acceleration"),
        ):
            if line.strip().startswith(label):
                last[key] = line.split()[-2]  # the last second's RMS [mm], then max |dtau|
    assert set(last) == {"adaptive", "frozen", "rac"}, printed
    assert (
        f"{last['adaptive']} mm adapting, {last['frozen']} mm frozen, {last['rac']} mm under resolved "
        f"acceleration control"
    ) in readme
    info = subprocess.run(
        [sys.executable, "-m", "robotgen", "info", str(RMAC)], capture_output=True, text=True, cwd=ROOT
    )
    radius = info.stdout.split("spectral radius ")[1].split()[0]
    assert f"spectral radius at the start pose ({radius})" in readme
