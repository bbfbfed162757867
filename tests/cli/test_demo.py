"""examples/demo.py, the README's first command: it runs what it can (a spec whose root is
one chain or formulas leaf), keeps every joint inside its limits, and turns away robot
trees and controllers with a message that says where to go instead."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def demo(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "examples/demo.py", *args], capture_output=True, text=True, cwd=ROOT)


@pytest.mark.parametrize("spec", ["puma560", "stanford"])
def test_demo_tracks_inside_the_joint_limits(spec):
    """Stanford's prismatic joint lives in [0.3048, 1.27] m: the trajectory stays there."""
    r = demo(f"specs/{spec}.yaml")
    assert r.returncode == 0, r.stderr
    assert "inside the joint limits" in r.stdout and "OUTSIDE" not in r.stdout
    rows = [line.split() for line in r.stdout.splitlines() if re.match(r"^\s*\d\.\d\d\s", line)]
    errors = np.array([float(row[1]) for row in rows])
    assert errors[0] > 1e-2 and errors[-1] < 1e-4  # the 0.05 offset decays under computed torque


@pytest.mark.parametrize("spec, says", [("styx_high_ct", "robotgen simulate specs/styx_high_ct.yaml"),
                                        ("puma560_rmrc", "resolved_rate controller")])
def test_demo_turns_away_what_it_cannot_run(spec, says):
    r = demo(f"specs/{spec}.yaml")
    assert r.returncode == 2
    assert says in r.stderr and "Traceback" not in r.stderr
