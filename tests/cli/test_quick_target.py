"""`make test-quick`, the README's first check: a sample of the suite named by paths in the
Makefile. Every path must exist and be collected (a renamed test file would silently shrink
the sample), and the sample must reach every layer."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def quick_tests() -> list[str]:
    text = (ROOT / "Makefile").read_text().replace("\\\n", " ")
    return re.search(r"^QUICK_TESTS \?= (.*)$", text, re.M).group(1).split()


def test_the_quick_sample_exists_and_spans_the_layers():
    paths = quick_tests()
    assert all((ROOT / p).exists() for p in paths), [p for p in paths if not (ROOT / p).exists()]
    layers = {p.split("/")[1] for p in paths}
    assert {"spec", "dynamics", "emit", "control", "cli"} <= layers
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    collected = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", *paths],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
    )
    assert collected.returncode == 0, collected.stdout[-2000:] + collected.stderr
    count = int(re.search(r"(\d+)(?:/\d+)? tests? (?:collected|selected)", collected.stdout).group(1))
    total = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
    )
    everything = int(re.search(r"(\d+)(?:/\d+)? tests? (?:collected|selected)", total.stdout).group(1))
    assert 300 <= count < everything, (count, everything)


LINT = [
    "python -m ruff check .",
    "python -m ruff format --check .",
    "python -m mypy",
]  # mypy's files and settings: pyproject.toml [tool.mypy]
# pytest-xdist, a worker per core; a test file goes whole to one worker, so its module's builds
# are made once
JOBS = ["-n", "auto", "--dist", "loadfile"]


def plan_of(target: str) -> list[str]:
    """The commands ``make -n target`` would run."""
    plan = subprocess.run(
        ["make", "--no-print-directory", "-n", target, "PYTHON=python"], capture_output=True, text=True, cwd=ROOT
    )  # run from make test, make would name the directory it enters
    assert plan.returncode == 0, plan.stderr
    return plan.stdout.splitlines()


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_lint_runs_ruff_its_formatter_check_then_mypy():
    assert plan_of("lint") == LINT


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_test_quick_runs_lint_then_the_sample():
    lines = plan_of("test-quick")
    assert lines[: len(LINT)] == LINT
    assert lines[len(LINT)].split() == ["python", "-m", "pytest", "-q", *JOBS, *quick_tests()]
    assert len(lines) == len(LINT) + 1, lines


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_test_runs_lint_then_the_suite():
    assert plan_of("test") == [*LINT, " ".join(["python -m pytest -q", *JOBS])]
