"""`robotgen simulate`: exit statuses, the CSV (header, rows, values that follow the closed-loop
error of §3.4) and the PNG, run as a user runs it (a subprocess in the project root)."""
from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from reference import const

ROOT = Path(__file__).resolve().parent.parent
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
    assert header == (["t"] + [f"x_{c}" for c in coords] + [f"xref_{c}" for c in coords]
                      + [f"tau_{k}" for k in range(1, 5)])
    with open(HIGH) as f:
        sim = yaml.safe_load(f)["simulation"]
    dt = const(sim["dt"])
    assert rows.shape == (501, 11)  # t = 0, dt, ..., 0.5 with the spec's dt = 1e-3
    np.testing.assert_allclose(rows[:, 0], np.arange(501) * dt, atol=1e-9)
    start = np.array([const(c) for c in sim["start"]])
    e0 = np.array([const(c) for c in sim["initial_error"]])
    np.testing.assert_allclose(rows[0, 1:4], start + e0, atol=1e-9)  # the plant starts off the target
    np.testing.assert_allclose(rows[0, 4:7], start, atol=1e-12)  # x_d(0) = start
    a = np.array([const(c) for c in sim["amplitude"]])
    w = 2 * math.pi * np.array([const(c) for c in sim["frequency"]])
    np.testing.assert_allclose(rows[:, 4:7], start + a * np.sin(np.outer(rows[:, 0], w)), atol=1e-9)
    assert np.all(np.isfinite(rows[:, 7:])) and np.abs(rows[:, 7:]).max() > 1e-3
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
