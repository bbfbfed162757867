"""Smoke test of bench/scaling.py --quick: chains of 2 and 6 links are built (timed in parts),
checked against CasADi, timed by the C harness, and the table, JSON and PNG come out (the
real scaling run, 2..30 links and a humanoid tree, is part of `make bench`)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import ROOT


@pytest.mark.slow  # bench/scaling.py's quick mode; `make bench` runs the full one
def test_scaling_quick(tmp_path):
    out, png = tmp_path / "scaling.json", tmp_path / "scaling.png"
    cmd = [sys.executable, str(ROOT / "bench" / "scaling.py"), "--quick", "--json", str(out), "--png", str(png)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "ns" in res.stdout and "chain6" in res.stdout
    data = json.loads(out.read_text())
    assert [m["dof"] for m in data["models"]] == [2, 6]
    for m in data["models"]:
        assert m["compile_timed_apart"]
        assert abs(m["build_s"] - (m["graph_s"] + m["emit_s"] + m["compile_s"])) < 1e-6
        assert m["check_vs_casadi"] <= 1e-9
        assert set(m["ns"]) == {"mass", "inverse_dynamics", "gravity", "jacobian", "coriolis", "forward_dynamics"}
        assert all(v > 0 for v in m["ns"].values())
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
