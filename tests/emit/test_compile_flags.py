"""$CFLAGS reaches the extension's compile and the build cache. -std=c99 -ffp-contract=off
come after it (no a * b + c fused into one multiply-add), so a build for this CPU's widest
instruction set at -O3 computes the same bits as the portable -O2 build, with gcc and clang."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from robots import PANDA, robots_dir

from robotgen.cli import main

NATIVE = "-O3 -march=native"
TWO_LINK = Path(__file__).resolve().parents[2] / "specs" / "two_link.yaml"


def load(out: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, next(out.glob(f"{name}.*so")))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def set_cflags(monkeypatch, cflags: str | None) -> None:
    if cflags is None:
        monkeypatch.delenv("CFLAGS", raising=False)
    else:
        monkeypatch.setenv("CFLAGS", cflags)


def build_panda(out: Path, monkeypatch, cflags: str | None) -> None:
    set_cflags(monkeypatch, cflags)
    assert (
        main(["build", str(robots_dir() / PANDA[0]), "--tip", PANDA[1], "--name", "pandaflags", "-o", str(out), "-q"])
        == 0
    )


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_a_native_build_computes_the_portable_builds_bits(tmp_path, monkeypatch, cc):
    """Every function of the Panda (trig, straight-line and looped kernels, a Cholesky solve),
    random states, compared bit for bit. (clang fuses within an expression unless told not to.)"""
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} is not installed")
    monkeypatch.setenv("CC", cc)
    portable, native = tmp_path / "portable", tmp_path / "native"
    build_panda(portable, monkeypatch, None)
    build_panda(native, monkeypatch, NATIVE)
    a, b = load(portable, "pandaflags"), load(native, "pandaflags")
    functions = json.loads((portable / "manifest.json").read_text())["functions"]
    rng = np.random.default_rng(11)
    compared = 0
    for f in functions:
        for _ in range(20):
            args = [
                rng.uniform(-3, 3, port["shape"]) if port["name"] != "dt" else np.array([1e-3]) for port in f["inputs"]
            ]
            x, y = getattr(a, f["name"])(*args), getattr(b, f["name"])(*args)
            x, y = (r if isinstance(r, tuple) else (r,) for r in (x, y))
            for u, v in zip(x, y):
                assert np.asarray(u).tobytes() == np.asarray(v).tobytes(), f["name"]
                compared += 1
    assert compared >= 20 * len(functions) >= 20 * 15


def test_cflags_are_part_of_the_build_key(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    for cflags, up_to_date in (("-O2", False), ("-O2", True), ("-O1", False), (None, False)):
        set_cflags(monkeypatch, cflags)
        assert main(["build", str(TWO_LINK), "-o", str(out)]) == 0
        assert ("up to date" in capsys.readouterr().out) == up_to_date, cflags


def test_flags_the_compiler_rejects_are_the_users_to_mend(tmp_path, monkeypatch, capsys):
    """Exit 1 (not a robotgen bug), the flags named, and no output directory left."""
    monkeypatch.setenv("CFLAGS", "-fno-such-flag")
    out = tmp_path / "out"
    assert main(["build", str(TWO_LINK), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "CFLAGS='-fno-such-flag'" in err and "unset CFLAGS" in err
    assert any(line.startswith("$ ") and "-O2 -fPIC -fno-such-flag -std=c99" in line for line in err.splitlines())
    assert not out.exists() and not list(tmp_path.iterdir())
