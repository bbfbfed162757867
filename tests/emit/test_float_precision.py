"""`--precision float` against double for the examples: M, inverse dynamics and forward
dynamics of the leaves, the servo step of the trees, on random inputs. The relative error
(largest difference over the largest magnitude of each output) is printed per function and
must stay within FLOAT_BOUND, the bound docs/c-api.md states."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from robotgen.cli import main

SPECS = Path(__file__).resolve().parents[2] / "specs"
FLOAT_BOUND = 1e-3  # docs/c-api.md (measured: <= 2e-6 for the leaves, <= 8e-5 for the servo steps)
CASES = {
    "two_link": ["mass", "inverse_dynamics", "forward_dynamics"],
    "puma560": ["mass", "inverse_dynamics", "forward_dynamics"],
    "stanford": ["mass", "inverse_dynamics", "forward_dynamics"],
    "styx_finger": ["mass", "inverse_dynamics", "forward_dynamics"],
    "styx_high_ct": ["servo_step"],
    "styx_redundant": ["servo_step"],
    "tripod_grasp": ["servo_step"],
}


def build(spec: str, precision: str, tmp: Path):
    name = f"{spec}_{precision}"
    text = (SPECS / f"{spec}.yaml").read_text().replace(f"name: {spec}\n", f"name: {name}\n", 1)
    path = tmp / f"{name}.yaml"
    path.write_text(text)
    assert main(["build", str(path), "-o", str(tmp / name), "--precision", precision, "-q"]) == 0
    sys.path.insert(0, str(tmp / name))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(tmp / name))


def inputs(module, function: str, rng) -> list[np.ndarray]:
    """Random values of the function's input shapes (manifest.json); dt small and positive."""
    manifest = json.loads((Path(module.__file__).parent / "manifest.json").read_text())
    ports = next(f["inputs"] for f in manifest["functions"] if f["name"] == function)
    values = []
    for port in ports:
        value = rng.normal(size=port["shape"]) * 0.5
        values.append(np.abs(value) * 1e-2 + 1e-3 if port["name"] == "dt" else value)
    return values


# the Stanford arm and the tripod grasp repeat what the PUMA and the Styx hands check: `make test-slow`
SLOW_CASES = {"stanford", "tripod_grasp"}


@pytest.mark.parametrize(
    "spec", [pytest.param(spec, marks=pytest.mark.slow) if spec in SLOW_CASES else spec for spec in CASES]
)
def test_float_agrees_with_double(tmp_path, spec):
    double, single = build(spec, "double", tmp_path), build(spec, "float", tmp_path)
    rng = np.random.default_rng(8)
    worst = {}
    for function in CASES[spec]:
        for _ in range(50):
            args = inputs(double, function, rng)
            want, got = getattr(double, function)(*args), getattr(single, function)(*args)
            want, got = (want, got) if isinstance(want, tuple) else ((want,), (got,))
            for w, g in zip(want, got):
                error = float(np.abs(w - g).max() / max(np.abs(w).max(), 1e-12))
                worst[function] = max(worst.get(function, 0.0), error)
    print(spec, {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= FLOAT_BOUND, worst
