"""Smoke test of bench/run.py: the C harness compiles against a generated header and the
three timings come out for a small spec (the real benchmark is `make bench`)."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT, SPECS


def test_bench_runs_on_two_link(tmp_path):
    out = tmp_path / "results.json"
    cmd = [
        sys.executable,
        str(ROOT / "bench" / "run.py"),
        "--spec",
        str(SPECS / "two_link.yaml"),
        "--quick",
        "--functions",
        "mass",
        "gravity",
        "--json",
        str(out),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    data = json.loads(out.read_text())
    assert data["robot"] == "two_link" and data["nq"] == 2
    assert [r["function"] for r in data["functions"]] == ["mass", "gravity"]
    for r in data["functions"]:
        assert r["c"]["ns_min"] > 0
        assert r["python"]["ns_single"] > 0 and r["casadi"]["ns_single"] > 0
