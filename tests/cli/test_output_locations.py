"""Where robotgen and the examples write when told nothing: under generated/ of the current
directory (robotgen build's default), which the repository ignores, and never beside the
sources. `robotgen simulate` and every example script with an output option default there."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted((ROOT / "examples").rglob("*.py"))


def ignored(path: str) -> bool:
    """Whether git ignores ``path`` (relative to the repository root; it need not exist)."""
    return subprocess.run(["git", "check-ignore", "-q", "--no-index", path], cwd=ROOT).returncode == 0


needs_git = pytest.mark.skipif(
    shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs git and a checkout"
)


def test_simulate_writes_under_generated(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "robotgen",
            "simulate",
            str(ROOT / "specs" / "styx_high_ct.yaml"),
            "--duration",
            "0.05",
            "-q",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
    )
    assert r.returncode == 0, r.stderr
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    assert written == [
        "generated/styx_high_ct_simulation/.robotgen-files",  # the record of what it wrote
        "generated/styx_high_ct_simulation/styx_high_ct.csv",
        "generated/styx_high_ct_simulation/styx_high_ct.png",
    ]
    assert "robotgen: wrote generated/styx_high_ct_simulation/styx_high_ct.csv" in r.stdout


def defaults(script: Path) -> list[str]:
    """The default output paths a script's --help names."""
    r = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.startswith("usage:"), (script, r.stderr)
    text = " ".join(r.stdout.split())
    named = re.findall(r"default:? ([^\s),;]+)", text)
    return [p for p in named if "/" in p and not p.endswith(".yaml")]  # outputs, not the input spec


def test_every_example_answers_help_and_writes_under_generated():
    found = {}
    for script in SCRIPTS:
        found[script.relative_to(ROOT).as_posix()] = defaults(script)
    outputs = [p for paths in found.values() for p in paths]
    assert len(outputs) >= 4, found  # the three papers' directories and the iLQR plot
    assert all(p.startswith("generated/") for p in outputs), found


@needs_git
def test_what_they_write_is_ignored():
    for path in (
        "generated/styx_high_ct_simulation/styx_high_ct.csv",
        "generated/trajectory_optimisation.png",
        "generated/papers/lee_lee_1983/report.md",
        "generated/puma560/puma560.h",
        "examples/controller/puma560_ct",
        "examples/controller/build/puma560/puma560.c",
    ):
        assert ignored(path), path
    assert not ignored("examples/demo.py") and not ignored("specs/puma560.yaml")
