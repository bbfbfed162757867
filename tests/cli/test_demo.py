"""examples/demo.py, the README's first command: it runs what it can (a spec whose root is
one chain or formulas leaf), keeps every joint inside its limits, and turns away robot
trees and controllers with a message that says where to go instead. It leaves the module in
generated/<name>/ (where `robotgen build` puts it), so that the README's Python snippet that
follows imports it, and a second run does not rebuild it."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def demo(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The demo run from ``cwd`` (where it writes generated/), as a user runs it from a clone."""
    return subprocess.run(
        [sys.executable, str(ROOT / "examples" / "demo.py"), *args], capture_output=True, text=True, cwd=cwd
    )


@pytest.mark.parametrize("spec", ["puma560", "stanford"])
def test_demo_tracks_inside_the_joint_limits(spec, tmp_path):
    """Stanford's prismatic joint lives in [0.3048, 1.27] m: the trajectory stays there."""
    r = demo(str(ROOT / "specs" / f"{spec}.yaml"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "inside the joint limits" in r.stdout and "OUTSIDE" not in r.stdout
    rows = [line.split() for line in r.stdout.splitlines() if re.match(r"^\s*\d\.\d\d\s", line)]
    errors = np.array([float(row[1]) for row in rows])
    assert errors[0] > 1e-2 and errors[-1] < 1e-4  # the 0.05 offset decays under computed torque


@pytest.mark.parametrize(
    "spec, says",
    [("styx_high_ct", "robotgen simulate specs/styx_high_ct.yaml"), ("puma560_rmrc", "resolved_rate controller")],
)
def test_demo_turns_away_what_it_cannot_run(spec, says):
    r = demo(f"specs/{spec}.yaml", cwd=ROOT)
    assert r.returncode == 2
    assert says in r.stderr and "Traceback" not in r.stderr


def test_the_readme_snippet_imports_what_the_first_command_left(tmp_path):
    """The README's first command (`python examples/demo.py`) builds generated/puma560; its
    first Python snippet, run from the same directory, imports it; the demo run again does
    not rebuild the unchanged spec."""
    first = demo(cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert "robotgen: built puma560" in first.stdout and (tmp_path / "generated" / "puma560" / "puma560.h").is_file()
    readme = (ROOT / "README.md").read_text()
    assert "python examples/demo.py" in readme.split("```")[1]
    snippet = next(block for block in readme.split("```python\n")[1:]).split("```")[0]
    assert 'sys.path.insert(0, "generated/puma560")' in snippet
    ran = subprocess.run([sys.executable, "-c", snippet], capture_output=True, text=True, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    header = tmp_path / "generated" / "puma560" / "puma560.h"
    built_at = header.stat().st_mtime_ns
    again = demo(cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "robotgen: generated/puma560 is up to date" in again.stdout and "robotgen: built" not in again.stdout
    assert header.stat().st_mtime_ns == built_at
