"""`robotgen simulate`: exit statuses, the CSV (header, rows, values that follow the closed-loop
error of §3.4) and the PNG, run as a user runs it (a subprocess in the project root)."""

from __future__ import annotations

import csv
import hashlib
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from reference import const

ROOT = Path(__file__).resolve().parents[2]
HIGH = ROOT / "specs" / "styx_high_ct.yaml"


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robotgen", *args], capture_output=True, text=True, cwd=ROOT)


def test_simulate_writes_csv_and_png(tmp_path):
    out = tmp_path / "sim"
    r = run_cli("simulate", "specs/styx_high_ct.yaml", "-o", str(out), "--duration", "0.5")
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    csv_path, png_path = out / "styx_high_ct.csv", out / "styx_high_ct.png"
    assert str(csv_path) in r.stdout and "simulated 0.500 s in 500 steps" in r.stdout

    with open(csv_path, newline="") as f:
        table = list(csv.reader(f))
    header, rows = table[0], np.array(table[1:], dtype=float)
    coords = ["x", "y", "psi"]
    assert header == (
        ["t"]
        + [f"x_{c}" for c in coords]
        + [f"xref_{c}" for c in coords]
        + [f"tau_{j}" for j in ("lth1", "lth2", "rth1", "rth2")]
        + ["f_hand_f1"]
    )
    with open(HIGH) as f:
        sim = yaml.safe_load(f)["simulation"]
    dt = const(sim["dt"])
    assert rows.shape == (501, 12)  # t = 0, dt, ..., 0.5 with the spec's dt = 1e-3
    np.testing.assert_allclose(rows[:, 0], np.arange(501) * dt, atol=1e-9)
    start = np.array([const(c) for c in sim["start"]])
    e0 = np.array([const(c) for c in sim["initial_error"]])
    np.testing.assert_allclose(rows[0, 1:4], start + e0, atol=1e-9)  # the plant starts off the target
    np.testing.assert_allclose(rows[0, 4:7], start, atol=1e-12)  # x_d(0) = start
    a = np.array([const(c) for c in sim["amplitude"]])
    w = 2 * math.pi * np.array([const(c) for c in sim["frequency"]])
    np.testing.assert_allclose(rows[:, 4:7], start + a * np.sin(np.outer(rows[:, 0], w)), atol=1e-9)
    assert np.all(np.isfinite(rows[:, 7:11])) and np.abs(rows[:, 7:11]).max() > 1e-3
    # critically damped computed torque (kp = 100, kv = 20): e(t) = e0 (1 + 10 t) exp(-10 t), up to
    # the zero-order hold's 1.9e-3 |e0| at dt = 1e-3 (test_primitives measures it)
    for k in (100, 250, 500):
        t = rows[k, 0]
        e = rows[k, 1:4] - rows[k, 4:7]
        np.testing.assert_array_less(np.abs(e - e0 * (1 + 10 * t) * math.exp(-10 * t)), 4e-3 * np.abs(e0))

    png = png_path.read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_simulate_rejects_a_single_chain(tmp_path):
    out = tmp_path / "sim"
    r = run_cli("simulate", "specs/two_link.yaml", "-o", str(out))
    assert r.returncode == 2
    assert "simulate needs a robot tree" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def spec_with(tmp_path, base: Path, change) -> Path:
    data = yaml.safe_load(base.read_text())
    change(data)
    path = tmp_path / base.name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_a_diverging_loop_is_the_users_gains(tmp_path):
    """PD gains far too high for the step: exit 1 at the controller's line, with the time
    and the state that blew up; no output directory."""

    def stiff(data):
        data["nodes"]["ct_hand"]["control"].update(law="pd", kp=1e6, kv=1e3)

    spec = spec_with(tmp_path, HIGH, stiff)
    out = tmp_path / "sim"
    r = run_cli("simulate", str(spec), "-o", str(out), "--dt", "0.01", "--duration", "0.5")
    assert r.returncode == 1, r.stderr
    line = spec.read_text().splitlines().index("  ct_hand:") + 1
    assert r.stderr.startswith(f"{spec}:{line}:3: the closed loop diverged at t = "), r.stderr
    assert "theta = [" in r.stderr and "lower kp and kv, or dt" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_initial_error_needs_start_not_theta0(tmp_path):
    spec = spec_with(tmp_path, HIGH, lambda d: d["simulation"].update(theta0=[2.0, 0.3, 1.1, 2.8]))
    r = run_cli("check", str(spec))
    assert r.returncode == 1
    assert "simulation.initial_error: initial_error offsets the plant from start" in r.stderr


def test_simulation_lists_are_checked_at_their_lines(tmp_path):
    def wrong(data):
        data["simulation"].update(start=[0.0, 0.12], amplitude=[0.01, 0.01, 0.2, 0.0], theta0=[1.0, 2.0])
        del data["simulation"]["initial_error"]

    spec = spec_with(tmp_path, HIGH, wrong)
    r = run_cli("check", str(spec))
    assert r.returncode == 1
    lines = spec.read_text().splitlines()
    found = {}
    for message in r.stderr.strip().splitlines():
        where, text = message.split(": ", 1)
        found[text.split(":")[0]] = int(where.split(":")[1])
    for key in ("start", "amplitude", "theta0"):
        assert lines[found[f"simulation.{key}"] - 1].strip().startswith(f"{key}:"), (key, r.stderr)
    assert "simulation.start: expected 3 entries (one per root coordinate of 'ct_hand': x, y, psi), got 2" in r.stderr
    assert "simulation.theta0: expected 4 entries (one per joint of the leaves (left, right)" in r.stderr


def test_a_theta0_off_the_grasp_reports_the_residual(tmp_path, build_module):
    """The right fingertip moved off its contact point: the constraint residual, at theta0."""
    module = build_module(HIGH)
    theta = module.plant_inverse(np.array([0.0, 0.12, 0.0]))
    assert np.abs(module.constraint_residual(theta)).max() < 1e-12
    theta_off = theta.copy()
    theta_off[2] += 0.01  # the right finger's first joint turned by 10 mrad

    def at(data):
        del data["simulation"]["initial_error"]
        data["simulation"]["theta0"] = [float(v) for v in theta_off]

    spec = spec_with(tmp_path, HIGH, at)
    r = run_cli("simulate", str(spec), "-o", str(tmp_path / "sim"))
    assert r.returncode == 1
    residual = module.constraint_residual(theta_off)
    worst = int(np.argmax(np.abs(residual)))
    name = module.info()["constraint_residual"][worst]
    assert name.startswith("hand.")
    line = spec.read_text().splitlines().index("  theta0:") + 1
    assert r.stderr.startswith(
        f"{spec}:{line}:3: simulation.theta0: theta0 violates the constraint of attach "
        f"'hand': residual {residual[worst]:.3g} in '{name[5:]}'"
    ), r.stderr
    assert abs(residual[worst]) > 1e-4


def test_a_chain_under_computed_torque_starts_mid_range(tmp_path):
    """No simulation section: the chain starts at its joints' mid-range posture (zero where
    a joint has no limits) and the loop holds it."""
    spec = tmp_path / "arm_ct.yaml"
    spec.write_text("""robotgen: 1
name: arm_ct
root: ct
nodes:
  arm:
    define:
      chain:
        convention: dh_standard
        joints:
          - {type: revolute, dh: {a: 0.5, alpha: "pi/2"}, link: {mass: 1, com: [-0.25, 0, 0]}, limits: {lower: -1, upper: 2}}
          - {type: revolute, dh: {a: 0.5}, link: {mass: 1, com: [-0.25, 0, 0]}}
  ct:
    control: {robot: arm, law: computed_torque, kp: 100, kv: 20}
""")
    out = tmp_path / "sim"
    r = run_cli("simulate", str(spec), "-o", str(out), "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    with open(out / "arm_ct.csv", newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == ["t", "x_q1", "x_q2", "xref_q1", "xref_q2", "tau_q1", "tau_q2"]
    rows = np.array(table[1:], dtype=float)
    np.testing.assert_allclose(rows[0, 1:3], [0.5, 0.0], atol=1e-12)
    assert np.abs(rows[:, 1:3] - rows[:, 3:5]).max() < 1e-9  # held against gravity
    assert np.abs(rows[:, 6]).max() > 1.0  # it takes torque on q2 to hold the arm against gravity


def test_internal_forces_carried_by_the_grasp(tmp_path):
    """styx_redundant resolves the squeeze to 1 N: the plant's readback of the force the
    grasp carries stays within 1 % of it (the fingers' own inertia makes the difference),
    and the CSV and PNG show it."""
    out = tmp_path / "sim"
    r = run_cli("simulate", "specs/styx_redundant.yaml", "-o", str(out), "--duration", "1.0")
    assert r.returncode == 0, r.stderr
    with open(out / "styx_redundant.csv", newline="") as f:
        table = list(csv.reader(f))
    assert table[0][-1] == "f_hand_f1"
    f = np.array([row[-1] for row in table[1:]], dtype=float)
    print(f"\n  styx_redundant squeeze over 1 s: min {f.min():.4f}, max {f.max():.4f} N (commanded 1)")
    assert np.abs(f - 1.0).max() < 0.01 and np.abs(f - 1.0).max() > 1e-5


def test_simulate_overwrites_only_what_it_wrote(tmp_path):
    """.robotgen-files holds the sha256 of the CSV and PNG simulate wrote; a later run replaces
    them (and leaves the user's other files); an edited CSV is the user's and is refused."""
    from robotgen.output_files import write_files, write_problem

    out = tmp_path / "sim"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    r = run_cli("simulate", "specs/styx_high_ct.yaml", "-o", str(out), "--duration", "0.01", "-q")
    assert r.returncode == 0, r.stderr
    names = ["styx_high_ct.csv", "styx_high_ct.png"]
    record = json.loads((out / ".robotgen-files").read_text())["files"]
    assert {n: record[n] for n in names} == {n: [hashlib.sha256((out / n).read_bytes()).hexdigest()] for n in names}
    assert sorted(p.name for p in out.iterdir()) == sorted([".robotgen-files", "notes.txt", *names])
    made = tmp_path / "made.csv"
    made.write_text("t\n0\n")
    assert write_problem(out, names) is None
    write_files(out, {"styx_high_ct.csv": made})  # what the next run does with its CSV
    assert (out / "styx_high_ct.csv").read_text() == "t\n0\n" and (out / "notes.txt").read_text() == "mine"
    with open(out / "styx_high_ct.csv", "a") as f:
        f.write("1\n")
    assert "changed since robotgen wrote them (styx_high_ct.csv)" in write_problem(out, names)


@pytest.mark.parametrize("case", ["a user's CSV", "a user's PNG", "-o FILE", "the spec at the CSV's name"])
def test_simulate_refuses_before_it_simulates(tmp_path, case):
    """simulate -o DIR overwrote DIR/<name>.csv and .png silently, and -o FILE was an internal
    error (FileExistsError): now exit 1 naming the path, before anything is built."""
    out = tmp_path / "sim"
    out.mkdir()
    spec = "specs/styx_high_ct.yaml"
    if case == "a user's CSV":
        (out / "styx_high_ct.csv").write_text("t,x\n0,1\n")
    elif case == "a user's PNG":
        (out / "styx_high_ct.png").write_bytes(b"\x89PNG my holiday")
    elif case == "-o FILE":
        out = tmp_path / "results.txt"
        out.write_text("mine")
    else:
        spec = str(out / "styx_high_ct.csv")  # a spec may have any name
        Path(spec).write_text(HIGH.read_text())
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    start = time.perf_counter()
    r = run_cli("simulate", spec, "-o", str(out), "-q")
    assert r.returncode == 1 and r.stderr.startswith(f"robotgen: error: {out}"), r.stderr
    assert time.perf_counter() - start < 20  # refused before the build and the simulation
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
