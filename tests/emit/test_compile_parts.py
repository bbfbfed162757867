"""A large module's <name>.c is compiled in parts at once (-DRG_PART=k): each function is in
exactly one part, the file without RG_PART holds them all, and the extension built from the
parts works. The threshold is lowered so that the two-link arm is split."""
from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robotgen.emit import compile as emit_compile
from robotgen.emit import context
from robotgen.emit.build import emit
from robotgen.frontend import load_system
from robotgen.model.describe import system_info, system_nq
from robotgen.symbolic import kernels_for

SPECS = Path(__file__).resolve().parents[2] / "specs"
pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="a C compiler is required")


def _defined(obj: Path) -> set[str]:
    out = subprocess.run(["nm", "--defined-only", str(obj)], capture_output=True, text=True, check=True).stdout
    return {line.split()[-1] for line in out.splitlines() if re.search(r" T ", line)}


def test_parts_partition_the_functions_and_the_module_works(tmp_path, monkeypatch):
    monkeypatch.setattr(context, "COMPILE_PARTS_ABOVE", 0)
    system = load_system(str(SPECS / "two_link.yaml"))
    out = tmp_path / "two_link"
    emit(out, "two_link_parts", kernels_for(system), nq=system_nq(system), extra_info=system_info(system))
    source = (out / "two_link_parts.c").read_text()
    assert "#if !defined(RG_PART) || RG_PART == 1" in source
    assert not list(out.glob("*.o")), "objects are removed"
    parts = []
    for k in range(context.COMPILE_PARTS):
        obj = tmp_path / f"part{k}.o"
        subprocess.run(["cc", "-std=c99", "-c", f"-DRG_PART={k}", str(out / "two_link_parts.c"), "-I", str(out),
                        "-o", str(obj)], check=True)
        parts.append(_defined(obj))
    whole = tmp_path / "whole.o"
    subprocess.run(["cc", "-std=c99", "-c", str(out / "two_link_parts.c"), "-I", str(out), "-o", str(whole)], check=True)
    assert all(p for p in parts) and not set.intersection(*parts)
    assert set.union(*parts) == _defined(whole)
    spec = importlib.util.spec_from_file_location("two_link_parts", out / f"two_link_parts{emit_compile.extension_suffix()}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    q = np.array([0.3, -0.7])
    M = module.mass(q)
    np.testing.assert_allclose(module.mass_inverse(q) @ M, np.eye(2), atol=1e-12)
