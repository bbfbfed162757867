"""Servo steps and forward dynamics (and its derivatives, and the discrete model) check what
they are given and what they make: status 1 and nothing written for a NaN or Inf input,
status 2 and every output zeroed for a result that is not finite (a singular M); the Python
module raises FloatingPointError naming the function. Other functions are not checked. A
function taking a step dt returns status 3 for dt <= 0 (ValueError in Python)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robotgen.cli import main

SPECS = Path(__file__).resolve().parents[2] / "specs"


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_python_raises_on_a_bad_input(build_module, bad):
    m = build_module(SPECS / "two_link.yaml")
    q, qd, tau = np.zeros(2), np.zeros(2), np.ones(2)
    assert np.all(np.isfinite(m.forward_dynamics(q, qd, tau)))
    qd[1] = bad
    with pytest.raises(FloatingPointError, match=r"forward_dynamics\(\): an input is NaN or infinite"):
        m.forward_dynamics(q, qd, tau)
    with pytest.raises(FloatingPointError, match=r"discrete_dynamics_derivatives\(\): an input"):
        m.discrete_dynamics_derivatives(q, qd, tau, 0.01)
    assert np.isnan(m.mass(np.array([0.0, bad]))).any()  # unchecked: NaN (or cos(inf)) in, NaN out (M reads q2)


def test_servo_step_of_a_tree_refuses_a_nan_state(build_module):
    m = build_module(SPECS / "styx_high_ct.yaml")
    theta = np.array([0.3, 1.2, -0.3, -1.2])
    state = m.servo_init(theta, np.zeros(4))
    args = [
        theta,
        np.zeros(4),
        np.array([0.0, 0.12, 0.0]),
        np.zeros(3),
        np.zeros(3),
        np.zeros(3),
        np.zeros(1),
        state,
        1e-3,
    ]
    tau, _ = m.servo_step(*args)
    assert np.all(np.isfinite(tau))
    args[0][2] = np.nan
    with pytest.raises(FloatingPointError, match=r"servo_step\(\): an input is NaN or infinite"):
        m.servo_step(*args)


def test_a_singular_mass_matrix_gives_status_2_and_zeros(tmp_path):
    """A chain whose last link carries nothing: M is singular, the Cholesky factor divides by
    zero, and forward dynamics returns 2 with its output zeroed, in C."""
    text = (SPECS / "two_link.yaml").read_text()
    start = text.index("          - name: elbow")
    text = text[:start] + text[start:].replace("mass: 0.9", "mass: 0").replace(
        "inertia: {ixx: 0.0005, iyy: 0.03, izz: 0.03, ixy: 0, ixz: 0, iyz: 0}", "inertia: {ixx: 0, iyy: 0, izz: 0}"
    )
    spec = tmp_path / "limp.yaml"
    spec.write_text(text.replace("name: two_link", "name: limp"))
    out = tmp_path / "limp"
    assert main(["build", str(spec), "-o", str(out), "--no-compile", "-q"]) == 0
    program = tmp_path / "main.c"
    program.write_text(
        '#include <math.h>\n#include <stdio.h>\n#include "limp.h"\n'
        "int main(void) {\n"
        "    double q[2] = {0.1, 0.2}, qd[2] = {0, 0}, tau[2] = {1, 1}, out[2] = {7, 7};\n"
        "    int s = limp_forward_dynamics(q, qd, tau, out);\n"
        '    printf("%d %g %g\\n", s, out[0], out[1]);\n'
        "    qd[0] = NAN; out[0] = out[1] = 7;\n"
        "    s = limp_forward_dynamics(q, qd, tau, out);\n"
        '    printf("%d %g %g\\n", s, out[0], out[1]);\n'
        "    return 0;\n}\n"
    )
    exe = tmp_path / "main"
    subprocess.run(
        [
            "cc",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            f"-I{out}",
            str(program),
            str(out / "limp.c"),
            "-lm",
            "-o",
            str(exe),
        ],
        check=True,
    )
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split("\n")
    assert lines[0] == "2 0 0"  # not finite: zeroed
    assert lines[1] == "1 7 7"  # NaN input: nothing written


# The checked functions docs/c-api.md lists for a chain with derivatives: forward dynamics and
# every derivative function (jacobian_derivative once returned NaN with status 0)
CHAIN_CHECKED = {
    "forward_dynamics",
    "inverse_dynamics_derivatives",
    "forward_dynamics_derivatives",
    "mass_inverse",
    "discrete_dynamics",
    "discrete_dynamics_derivatives",
    "jacobian_derivative",
}


def _finite(result) -> bool:
    return all(np.all(np.isfinite(r)) for r in (result if isinstance(result, tuple) else (result,)))


def _manifest(m) -> dict:
    manifest = json.loads((Path(m.__file__).parent / "manifest.json").read_text())
    return {f["name"]: f for f in manifest["functions"]}


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_every_documented_checked_function_of_a_chain_refuses_a_bad_input(build_module, bad):
    m = build_module(SPECS / "two_link.yaml")
    header = (Path(m.__file__).parent / "two_link.h").read_text()
    functions = _manifest(m)
    rng = np.random.default_rng(3)
    for name in sorted(CHAIN_CHECKED):
        block = header[header.index(f"/* two_link_{name}:\n") : header.index(f"int two_link_{name}(")]
        assert "checked: returns 1" in block, name
        args = [
            np.full(1, 0.01) if p["name"] == "dt" else rng.uniform(-1, 1, int(np.prod(p["shape"])))
            for p in functions[name]["inputs"]
        ]
        assert _finite(getattr(m, name)(*args)), name
        for k in range(len(args)):
            spoilt = [a.copy() for a in args]
            spoilt[k].flat[0] = bad
            with pytest.raises(FloatingPointError, match=rf"{name}\(\): an input is NaN or infinite"):
                getattr(m, name)(*spoilt)


@pytest.mark.parametrize(
    "spec, name",
    [
        ("two_link", "discrete_dynamics"),
        ("two_link", "discrete_dynamics_derivatives"),
        ("styx_high_ct", "servo_step"),
        ("styx_high_ct", "ct_hand_write"),
    ],
)
def test_a_step_that_is_not_positive_is_refused(build_module, spec, name):
    """dt = 0 or dt < 0 was accepted with status 0; now a ValueError naming dt (status 3),
    checked functions or not (a node's write is not checked: -inf is status 3 there, 1 in a
    checked one)."""
    m = build_module(SPECS / f"{spec}.yaml")
    rng = np.random.default_rng(5)
    args = {p["name"]: rng.uniform(-0.1, 0.1, int(np.prod(p["shape"]))) for p in _manifest(m)[name]["inputs"]}
    assert "dt" in args
    args["dt"] = 1e-3
    assert _finite(getattr(m, name)(**args))
    for dt in (0.0, -1e-3, -np.inf):
        checked_inf = np.isinf(dt) and name != "ct_hand_write"
        with pytest.raises(
            FloatingPointError if checked_inf else ValueError,
            match=rf"{name}\(\): " + ("an input is NaN" if checked_inf else r"dt must be positive"),
        ):
            getattr(m, name)(**{**args, "dt": dt})


def test_the_c_reports_a_step_that_is_not_positive_and_writes_nothing(tmp_path, build_module):
    """Status 3 from discrete_dynamics for dt = 0 and dt < 0, outputs untouched; a NaN dt is
    status 1 (checked), a positive one 0; jacobian_derivative: status 1 for a NaN."""
    out = Path(build_module(SPECS / "two_link.yaml").__file__).parent
    program = tmp_path / "main.c"
    program.write_text(
        '#include <math.h>\n#include <stdio.h>\n#include "two_link.h"\n'
        "int main(void) {\n"
        "    double q[2] = {0.1, 0.2}, qd[2] = {0.3, 0.4}, tau[2] = {1, 1}, qn[2], qdn[2], J[12];\n"
        "    double steps[4] = {0.0, -1e-3, NAN, 1e-3};\n"
        "    int k, s;\n"
        "    for (k = 0; k < 4; ++k) {\n"
        "        qn[0] = qn[1] = qdn[0] = qdn[1] = 7;\n"
        "        s = two_link_discrete_dynamics(q, qd, tau, &steps[k], qn, qdn);\n"
        '        printf("%d %g %g\\n", s, qn[0], qdn[1]);\n'
        "    }\n"
        "    J[0] = 7; q[1] = NAN;\n"
        '    printf("%d %g\\n", two_link_jacobian_derivative(q, qd, J), J[0]);\n'
        "    return 0;\n}\n"
    )
    exe = tmp_path / "main"
    subprocess.run(
        [
            "cc",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            f"-I{out}",
            str(program),
            str(out / "two_link.c"),
            "-lm",
            "-o",
            str(exe),
        ],
        check=True,
    )
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split("\n")
    assert lines[:3] == ["3 7 7", "3 7 7", "1 7 7"]
    status, q_next, qd_next = lines[3].split()
    assert status == "0" and float(q_next) != 7 and float(qd_next) != 7
    assert lines[4] == "1 7"
