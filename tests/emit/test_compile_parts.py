"""A large module's <name>.c is compiled in parts at once (-DRG_PART=k): each function is in
exactly one part, the file without RG_PART holds them all, and the extension built from the
parts works. The threshold is lowered so that the two-link arm is split."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from robotgen.emit import compile as emit_compile
from robotgen.emit import context
from robotgen.emit.pipeline import build
from robotgen.frontend import load_system

SPECS = Path(__file__).resolve().parents[2] / "specs"
pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="a C compiler is required")


def _defined(obj: Path) -> set[str]:
    out = subprocess.run(["nm", "--defined-only", str(obj)], capture_output=True, text=True, check=True).stdout
    return {line.split()[-1] for line in out.splitlines() if re.search(r" T ", line)}


def test_parts_partition_the_functions_and_the_module_works(tmp_path, monkeypatch):
    monkeypatch.setattr(context, "COMPILE_PARTS_ABOVE", 0)
    system = load_system(str(SPECS / "two_link.yaml"))
    out = tmp_path / "two_link"
    build(replace(system, name="two_link_parts"), out)  # a name of its own: the module is imported here
    source = (out / "two_link_parts.c").read_text()
    assert "#if !defined(RG_PART) || RG_PART == 1" in source
    assert not list(out.glob("*.o")), "objects are removed"
    parts = []
    for k in range(context.COMPILE_PARTS):
        obj = tmp_path / f"part{k}.o"
        subprocess.run(
            ["cc", "-std=c99", "-c", f"-DRG_PART={k}", str(out / "two_link_parts.c"), "-I", str(out), "-o", str(obj)],
            check=True,
        )
        parts.append(_defined(obj))
    whole = tmp_path / "whole.o"
    subprocess.run(
        ["cc", "-std=c99", "-c", str(out / "two_link_parts.c"), "-I", str(out), "-o", str(whole)], check=True
    )
    assert all(p for p in parts) and not set.intersection(*parts)
    assert set.union(*parts) == _defined(whole)
    spec = importlib.util.spec_from_file_location(
        "two_link_parts", out / f"two_link_parts{emit_compile.extension_suffix()}"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    q = np.array([0.3, -0.7])
    M = module.mass(q)
    np.testing.assert_allclose(module.mass_inverse(q) @ M, np.eye(2), atol=1e-12)


def _chain_spec(path: Path, n: int) -> Path:
    """An n-joint DH chain (past 12 joints its dynamics are loops, sharing rg_kinematics)."""
    joints = [
        {
            "name": f"j{i + 1}",
            "type": "revolute",
            "dh": {"a": 0.05 * (i % 3), "alpha": ["pi/2", "-pi/2", "0"][i % 3], "d": 0.1, "theta": 0},
            "link": {
                "mass": 1.0 + 0.1 * i,
                "com": [0.01, -0.02, 0.03],
                "inertia": {"ixx": 0.02, "iyy": 0.03, "izz": 0.01, "ixy": 0.001, "ixz": 0.0, "iyz": 0.0},
            },
        }
        for i in range(n)
    ]
    doc = {
        "robotgen": 1,
        "name": "chain13",
        "root": "arm",
        "nodes": {"arm": {"define": {"chain": {"convention": "dh_standard", "joints": joints}}}},
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_a_stage_helper_is_compiled_in_one_part_and_called_from_the_others(tmp_path, monkeypatch):
    """Each part compiles warning-free; rg_kinematics is defined in one part that calls it, the
    other parts that call it link to that one, the rest do not name it; the whole file (a
    user's build) keeps it static, the extension does not export it; the module equals the
    graphs."""
    monkeypatch.setattr(context, "COMPILE_PARTS_ABOVE", 0)
    monkeypatch.setattr(context, "COMPILE_PARTS", 8)  # more parts than looped kernels: some without
    system = load_system(str(_chain_spec(tmp_path / "chain13.yaml", 13)))
    out = tmp_path / "chain13"
    kernels = build(system, out).kernels
    source = (out / "chain13.c").read_text()
    assert source.count("RG_SHARED void rg_kinematics(") == 2  # the definition and one declaration
    # the kernels (a batch entry point's first parameter is an int: robotgen.emit.lanes)
    functions = re.findall(
        r"#if !defined\(RG_PART\) \|\| RG_PART == (\d)\n(int chain13_\w*\((?!int ).*?\n}\n)", source, re.S
    )
    calling = {int(k) for k, definition in functions if "  rg_kinematics(q, " in definition}
    assert len(calling) > 1 and set(range(context.COMPILE_PARTS)) - calling and len(functions) == len(kernels)

    def symbol(flags: list[str], name: str) -> str:
        obj = tmp_path / f"{name}.o"
        subprocess.run(
            [
                "cc",
                "-std=c99",
                "-O0",
                "-Wall",
                "-Wextra",
                "-Werror",
                "-c",
                *flags,
                str(out / "chain13.c"),
                "-I",
                str(out),
                "-o",
                str(obj),
            ],
            check=True,
        )
        symbols = subprocess.run(["nm", str(obj)], capture_output=True, text=True, check=True).stdout
        found = re.search(r"^\s*\S*\s+([A-Za-z]) rg_kinematics$", symbols, re.M)
        return found.group(1) if found else ""

    kinds = {k: symbol([f"-DRG_PART={k}"], f"part{k}") for k in range(context.COMPILE_PARTS)}
    defined = {k for k, kind in kinds.items() if kind == "T"}
    assert len(defined) == 1 and defined < calling, kinds
    assert {k for k, kind in kinds.items() if kind == "U"} == calling - defined, kinds
    assert not {kind for k, kind in kinds.items() if k not in calling} - {""}, kinds
    assert symbol([], "whole") == "t"
    exported = subprocess.run(
        ["nm", "-D", str(out / f"chain13{emit_compile.extension_suffix()}")], capture_output=True, text=True, check=True
    ).stdout
    assert "rg_kinematics" not in exported
    spec = importlib.util.spec_from_file_location("chain13", out / f"chain13{emit_compile.extension_suffix()}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    q, qd = np.linspace(-1, 1, 13), np.cos(np.arange(13))
    by_name = {k.name: k for k in kernels}
    for name, args in (("mass", (q,)), ("coriolis", (q, qd)), ("nonlinear", (q, qd))):
        assert by_name[name].schedule is not None and by_name[name].schedule.stages, name
        expected = np.array(by_name[name].function(*args)).reshape(getattr(module, name)(*args).shape)
        np.testing.assert_allclose(getattr(module, name)(*args), expected, rtol=1e-12, atol=1e-12)
