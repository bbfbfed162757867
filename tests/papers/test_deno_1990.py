"""examples/papers/deno_1990.py in quick mode: the numbers it reports for Deno, Murray, Pister
& Sastry 1990 (chapter 4 and Appendix A), and the files it writes.

The script's references are closed forms written from StyxDefinitions.m; here each number
is held to what the paper says (or, where it claims only a trend, to that trend)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "papers" / "deno_1990.py"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("deno_1990_script", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = script  # its dataclasses look their module up while it loads
    spec.loader.exec_module(script)
    out = tmp_path_factory.mktemp("deno_1990")
    return script.reproduce(out, quick=True), out


def test_appendix_a_masses_are_the_closed_forms(run):
    g, _ = run
    # RobotMass[left] (TwoLinkMass), RobotMass[hand] (eqs 3.4-3.8), RobotCoriolis[fingers] (eq 3.5)
    for key in ("a_left", "a_hand", "a_fingers_coriolis", "a_pd_left"):
        assert g[key] < 1e-12, (key, g[key])
    assert g["a_high_ct_hand"] == 0.0  # "this should be zero": exactly
    assert g["a_ff"] == 0.0  # the feedforward of Fig 4.3 leaves no mass either
    assert g["a_low_ct_hand"] < 1e-12 and g["a_multilevel_hand"] < 1e-12  # "just the box mass"
    # the uncontrolled hand does carry the fingers: what the controllers hide is not nothing
    assert g["a_hand_min_eig_over_box"] > 1e-4


def test_high_level_law_is_the_expanded_formula(run):
    g, _ = run
    assert g["s41_formula_rel"] < 1e-10
    assert g["s41_box_acceleration_rel"] < 1e-10  # the plant's box follows xdd_d + Kv e' + Kp e


def test_multilevel_moves_the_box_as_high_level_computed_torque(run):
    g, _ = run
    assert g["s43_pd_terms_rel"] < 1e-10  # on the resolved trajectory the PD terms are nil
    assert g["s43_box_wrench_rel"] < 1e-10 and g["s43_error_box_wrench_rel"] < 1e-10
    assert g["s43_box_acceleration_rel"] < 1e-10
    # the joint torques differ, by a squeeze that matches its closed form to the last digits
    assert g["s43_joint_torque_gap_median"] > 0.01 and g["s43_error_torque_gap_median"] > 0.01
    assert g["s43_high_level_squeeze"] < 1e-12
    assert g["s43_squeeze_rel"] < 1e-9
    # the squeeze the grasp carries: the fingers' under the high-level law, none under Fig 4.3's
    assert g["s43_high_carried_squeeze_rel"] < 1e-9 and g["s43_multi_carried_squeeze"] < 1e-9


def test_low_level_error_grows_with_box_mass_and_high_level_does_not(run):
    g, _ = run
    n = sum(k.startswith("sweep_mass_") for k in g)
    masses = np.array([g[f"sweep_mass_{i}"] for i in range(n)])
    assert n >= 3 and masses[0] == 0.0 and np.all(np.diff(masses) > 0)
    for what in ("position", "angle"):
        high = np.array([g[f"fig41_{what}_rms_{i}"] for i in range(n)])
        low = np.array([g[f"fig42_{what}_rms_{i}"] for i in range(n)])
        assert np.all(np.diff(low) > 0), (what, low)
        assert low[-1] > 100 * high[-1], (what, low, high)
        assert high.max() < 1.2 * high.min(), (what, high)  # flat in the box mass
        assert low[0] < 1.1 * high[0], (what, low, high)  # massless box: the two are alike
    # Fig 4.1's error is the servo's zero-order hold: first order in the period, and small
    assert 1.8 < g["fig41_position_rms_0"] / g["fig41_position_rms_half_dt"] < 2.2
    assert all(g[f"fig41_position_rms_{i}"] < 2e-6 for i in range(n))
    assert all(g[f"fig41_angle_rms_{i}"] < 1e-5 for i in range(n))


def test_structures_on_one_path(run):
    g, _ = run
    assert g["fig42_position_rms_late"] > 10 * g["fig41_position_rms_late"]
    assert g["fig43_position_rms_late"] == pytest.approx(g["fig41_position_rms_late"], rel=0.05)
    assert g["fig43_max_squeeze_without_pd"] < 0.01 * g["fig43_max_squeeze"] < g["fig41_max_squeeze"]


def test_files_written(run):
    g, out = run
    for name in ("fig4_1", "fig4_2", "fig4_3", "structures", "box_mass_sweep"):
        data = (out / f"{name}.png").read_bytes()
        assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 10_000, name
    report = (out / "report.md").read_text()
    assert report.startswith("# Deno, Murray, Pister, Sastry 1990")
    assert '"this should be zero"' in report and '"just the box mass"' in report
    assert f"{g['s41_formula_rel']:.1e}" in report
    assert f"| {g['sweep_mass_1']:g} | {g['fig41_position_rms_1']:.2e} | {g['fig42_position_rms_1']:.2e} |" in report
