"""examples/papers/whitney_1972.py in quick mode: Fig 5's three-link arm under the optimal
linear servo, against the full nonlinear dynamics."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "examples" / "papers" / "whitney_1972.py"
JOINTS = ("sweep", "flexion", "elbow")


def load_script():
    spec = importlib.util.spec_from_file_location("whitney_1972_script", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up while it loads
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def script():
    return load_script()


@pytest.fixture(scope="module")
def reproduced(script, tmp_path_factory):
    """One run of the script's main in quick mode: (its output directory, the numbers its
    reproduce returned, what it printed)."""
    out = tmp_path_factory.mktemp("whitney_1972")
    kept, reproduce = {}, script.reproduce

    def keeping(*args, **kwargs):
        kept["numbers"] = reproduce(*args, **kwargs)
        return kept["numbers"]

    printed = io.StringIO()
    script.reproduce = keeping
    try:
        with contextlib.redirect_stdout(printed):
            script.main(["--quick", "-o", str(out)])
    finally:
        script.reproduce = reproduce
    return out, kept["numbers"], printed.getvalue()


def test_figure_and_report_are_written(reproduced):
    out, x, _ = reproduced
    png = (out / "fig5.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 20_000
    report = (out / "report.md").read_text()
    assert "![Fig 5](fig5.png)" in report and "errors are quite small" in report
    assert f"| servo, max | {1e3 * x['servo_max_error_sweep_rad']:.2f} |" in report
    assert f"| peak [ft-lb] | {x['servo_peak_torque_ftlb']:.2f} |" in report


def test_errors_stay_within_the_bound_from_the_design(reproduced):
    """|theta_i - theta_d,i| <= max |prediction on eq 19 - theta_d,i| + sum_j gamma_ij max |d_j|:
    e = x - x_linear obeys edot = A_c e + (0, d), d the linearisation residual along the run."""
    _, x, _ = reproduced
    for name in JOINTS:
        measured, linear, bound = (
            x[f"{k}_{name}_rad"] for k in ("servo_max_error", "servo_linear_max_error", "error_bound")
        )
        print(f"\n{name}: max error {measured:.2e} rad, eq 19 predicts {linear:.2e}, bound {bound:.2e}")
        assert measured <= bound
        assert bound < 0.01  # "the errors are quite small": below 0.6 degrees


def test_the_feedforward_beats_the_same_gains_on_the_error(reproduced):
    _, x, _ = reproduced
    for model in ("", "_linear"):
        s, r = f"servo{model}", f"regulator{model}"
        print(
            f"\n{model or 'nonlinear'}: max error {x[s + '_max_error_rad']:.2e} against {x[r + '_max_error_rad']:.2e}, "
            f"RMS {x[s + '_rms_error_rad']:.2e} against {x[r + '_rms_error_rad']:.2e}, cost {x[s + '_cost']:.4g} "
            f"against {x[r + '_cost']:.4g}"
        )
        assert x[s + "_max_error_rad"] < 0.5 * x[r + "_max_error_rad"]
        assert x[s + "_rms_error_rad"] < 0.5 * x[r + "_rms_error_rad"]
        assert x[s + "_cost"] < x[r + "_cost"]


def test_the_torques_are_those_the_path_needs(reproduced):
    """The servo's torque against inverse dynamics along the reference (generated RNEA)."""
    _, x, _ = reproduced
    needed = x["needed_peak_torque_nm"]
    print(
        f"\npeak torque {x['servo_peak_torque_nm']:.3f} N m, the path needs {needed:.3f}; largest "
        f"difference {x['servo_torque_minus_needed_nm']:.3f} N m"
    )
    assert x["servo_torque_minus_needed_nm"] < 0.05 * needed
    for name in JOINTS:
        assert abs(x[f"servo_peak_torque_{name}_nm"] - x[f"needed_peak_torque_{name}_nm"]) < 0.05 * needed
    assert x["servo_peak_torque_ftlb"] * 0.3048 * 4.4482216152605 == pytest.approx(x["servo_peak_torque_nm"])


def test_the_servo_is_the_direct_minimum_of_its_cost(reproduced):
    """The steady servo with g_f solves the finite problem with the terminal cost s^T P s - 2 g_f^T s;
    the same problem minimised directly over the whole horizon (sparse, extrapolated) agrees."""
    _, x, _ = reproduced
    print(
        f"\ndirect {x['direct_cost']:.10g}, servo {x['servo_linear_cost_with_terminal']:.10g}; inputs "
        f"{x['direct_input_gap_nm']:.2e} N m apart ({x['direct_input_coarse_gap_nm']:.2e} before extrapolation)"
    )
    assert x["direct_cost_relative_gap"] < 1e-8
    assert x["direct_input_gap_nm"] < 1e-5 * x["servo_linear_peak_torque_nm"]
    assert x["direct_input_gap_nm"] < 0.1 * x["direct_input_coarse_gap_nm"]
    assert x["closed_loop_slowest_real_part"] < 0


def test_main_prints_the_numbers_and_the_files(reproduced):
    out, x, printed = reproduced
    assert "servo_max_error_rad" in printed and f"wrote {out / 'fig5.png'}" in printed
    assert f"{'servo_max_error_sweep_rad':45s} {x['servo_max_error_sweep_rad']:.6g}" in printed
    assert (out / "report.md").exists()


def test_eq_11_arrives_at_T_where_the_fixed_horizon_approaches(reproduced):
    """Eq 11 with the remaining time: the hand at the target at T, half way at T/2, on the
    straight line; the fixed horizon h leaves exp(-T/h) of the distance (to first order in the
    period)."""
    out, x, _ = reproduced
    assert x["eq11_arrival_distance_at_T_m"] < 1e-6
    assert abs(x["eq11_arrival_distance_at_half_T_m"] - 0.1) < 1e-4
    assert x["eq11_arrival_largest_distance_off_line_m"] < 1e-4
    assert abs(x["eq11_exponential_distance_at_T_m"] / x["eq11_exponential_predicted_m"] - 1) < 0.01
    assert (out / "eq11.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert "![eq 11](eq11.png)" in (out / "report.md").read_text()
