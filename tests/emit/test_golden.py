"""What robotgen emits for specs/ is pinned in tests/golden/: every spec's manifest.json
(the sha256 of each emitted file) and the whole output of the small specs. A fresh build
must equal it byte for byte, on every machine: CI runs this file under several
OPENBLAS_CORETYPE values and with the lowest numpy and scipy that pyproject.toml allows.
Two builds in one process are equal too."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from golden.refresh import GOLDEN, emitted, golden_files

from robotgen.cli import main

ROOT = Path(__file__).resolve().parents[2]
SPECS = sorted((ROOT / "specs").glob("*.yaml"))
REFRESH = "run `make golden` (tests/golden/refresh.py) and review the diff"


@pytest.mark.parametrize("spec", SPECS, ids=[s.stem for s in SPECS])
def test_a_fresh_build_equals_the_golden_output(spec, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["build", str(spec), "-o", str(first), "--no-compile", "-q"]) == 0
    assert main(["build", str(spec), "-o", str(second), "--no-compile", "-q"]) == 0
    fresh = emitted(first)
    assert fresh == emitted(second), "two builds of one spec differ"
    name = next(first.glob("*.h")).stem
    golden = GOLDEN / name
    assert golden.is_dir(), f"tests/golden/{name} is missing: {REFRESH}"
    stored = {p.name: p.read_bytes() for p in golden.iterdir() if p.is_file()}
    expected = golden_files(name, first)
    assert sorted(stored) == sorted(expected), f"tests/golden/{name}: file sets differ: {REFRESH}"
    manifest, pinned = json.loads(expected["manifest.json"]), json.loads(stored["manifest.json"])
    changed = sorted(f for f in manifest["files"] if manifest["files"][f] != pinned["files"].get(f))
    assert not changed, f"tests/golden/{name}: {changed} differ from a fresh build: {REFRESH}"
    stale = sorted(f for f in expected if expected[f] != stored[f])
    assert not stale, f"tests/golden/{name}: {stale} differ from a fresh build: {REFRESH}"


def test_every_golden_directory_has_a_spec():
    names = {p.name for p in GOLDEN.iterdir() if p.is_dir() and not p.name.startswith(("_", "."))}
    built = set()
    for spec in SPECS:
        for line in spec.read_text().splitlines():
            if line.startswith("name:"):
                built.add(line.split(":", 1)[1].strip())
    assert names == built, f"golden directories without a spec: {sorted(names - built)}; {REFRESH}"
