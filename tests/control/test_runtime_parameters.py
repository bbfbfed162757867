"""Run-time gains and parameters from specs: a servo step with run-time gains at their
defaults equals the folded build; passing other gains equals a build folded with those
gains; a payload mass or formulas parameter marked {runtime: v} behaves as the spec value it
replaces; `gains: folded` reproduces the folded kernels byte for byte."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import yaml

from robotgen.cli import main

ROOT = Path(__file__).resolve().parents[2]
HIGH = ROOT / "specs" / "styx_high_ct.yaml"


def build(tmp_path: Path, data: dict, name: str):
    data = dict(data, name=name)
    spec = tmp_path / f"{name}.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / name
    assert main(["build", str(spec), "-o", str(out), "-q"]) == 0
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(out))


def servo_args(module, rng):
    theta = module.plant_inverse(np.array([0.0, 0.12, 0.1]))
    theta_dot = rng.normal(size=4) * 0.1
    x = np.array([0.005, 0.115, 0.15])
    v, a, f = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3) * 0.01
    state = module.servo_init(theta, theta_dot)
    return [theta, theta_dot, x, v, a, f, np.array([0.3]), state, np.array([1e-3])]


def test_runtime_gains_equal_folded_ones(tmp_path):
    data = yaml.safe_load(HIGH.read_text())
    runtime = build(tmp_path, data, "gains_runtime")
    folded_data = yaml.safe_load(HIGH.read_text())
    folded_data["nodes"]["ct_hand"]["control"]["gains"] = "folded"
    folded = build(tmp_path, folded_data, "gains_folded")
    other_data = yaml.safe_load(HIGH.read_text())
    other_data["nodes"]["ct_hand"]["control"].update(gains="folded", kp=[50, 60, 70], kv=7)
    other = build(tmp_path, other_data, "gains_other")
    assert runtime.parameters == {"ct_hand_kp": 100.0, "ct_hand_kv": 20.0}
    assert not hasattr(folded, "parameters")
    rng = np.random.default_rng(0)
    args = servo_args(runtime, rng)
    tau_r, state_r = runtime.servo_step(*args)
    tau_f, state_f = folded.servo_step(*args)
    np.testing.assert_allclose(tau_r, tau_f, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(state_r, state_f, rtol=1e-13, atol=1e-15)
    # a scalar gain is a scalar parameter: a per-axis gain needs the spec to say per axis
    data2 = yaml.safe_load(HIGH.read_text())
    data2["nodes"]["ct_hand"]["control"].update(kp=[100, 100, 100])
    per_axis = build(tmp_path, data2, "gains_per_axis")
    tau_o, _ = other.servo_step(*args)
    tau_p, _ = per_axis.servo_step(*args, ct_hand_kp=[50, 60, 70], ct_hand_kv=7.0)
    np.testing.assert_allclose(tau_p, tau_o, rtol=1e-13, atol=1e-15)
    assert np.abs(tau_p - tau_r).max() > 1e-6  # the gains do change the step


def test_gains_folded_prints_the_kernels_of_before(tmp_path):
    """styx_low_ct folds its gains: its kernel source is what a build without run-time
    parameters printed (the golden manifest pins it)."""
    import json

    out = tmp_path / "low"
    assert main(["build", str(ROOT / "specs" / "styx_low_ct.yaml"), "-o", str(out), "--no-compile", "-q"]) == 0
    text = (out / "styx_low_ct.c").read_text()
    assert "params" not in text
    golden = json.loads((ROOT / "tests" / "golden" / "styx_low_ct" / "manifest.json").read_text())
    import hashlib

    assert golden["files"]["styx_low_ct.c"] == hashlib.sha256(text.encode()).hexdigest()


def test_runtime_payload_mass_and_formulas_parameter(tmp_path):
    """The box's mass {runtime: 0.2} and a finger's link mass {runtime: 0.3}: at their defaults
    the plant equals the plain spec's; passing other values equals a spec written with them."""
    plain = yaml.safe_load(HIGH.read_text())
    marked = yaml.safe_load(HIGH.read_text())
    marked["nodes"]["box"]["define"]["rigid_body"]["planar"]["mass"] = {"runtime": 0.2}
    marked["nodes"]["left"]["define"]["formulas"]["parameters"]["m1"] = {"runtime": 0.3}
    heavier = yaml.safe_load(HIGH.read_text())
    heavier["nodes"]["box"]["define"]["rigid_body"]["planar"]["mass"] = 0.5
    heavier["nodes"]["left"]["define"]["formulas"]["parameters"]["m1"] = 0.45
    a, b, c = (
        build(tmp_path, plain, "mass_plain"),
        build(tmp_path, marked, "mass_marked"),
        build(tmp_path, heavier, "mass_heavier"),
    )
    assert b.parameters == {"left_m1": 0.3, "box_mass": 0.2, "ct_hand_kp": 100.0, "ct_hand_kv": 20.0}
    theta = a.plant_inverse(np.array([0.0, 0.12, 0.1]))
    v, tau = np.array([0.01, -0.02, 0.3]), np.array([0.01, 0.02, -0.01, 0.03])
    np.testing.assert_allclose(b.plant_dynamics(theta, v, tau)[1], a.plant_dynamics(theta, v, tau)[1], rtol=1e-13)
    np.testing.assert_allclose(
        b.plant_dynamics(theta, v, tau, box_mass=0.5, left_m1=0.45)[1], c.plant_dynamics(theta, v, tau)[1], rtol=1e-12
    )
    np.testing.assert_allclose(b.hand_mass(theta, box_mass=0.5, left_m1=0.45), c.hand_mass(theta), rtol=1e-12)
    assert np.abs(b.hand_mass(theta, box_mass=0.5) - a.hand_mass(theta)).max() > 1e-3
