"""Servo steps and forward dynamics (and its derivatives, and the discrete model) check what
they are given and what they make: status 1 and nothing written for a NaN or Inf input,
status 2 and every output zeroed for a result that is not finite (a singular M); the Python
module raises FloatingPointError naming the function. Other functions are not checked."""
from __future__ import annotations

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
    args = [theta, np.zeros(4), np.array([0.0, 0.12, 0.0]), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(1),
            state, 1e-3]
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
        "inertia: {ixx: 0.0005, iyy: 0.03, izz: 0.03, ixy: 0, ixz: 0, iyz: 0}", "inertia: {ixx: 0, iyy: 0, izz: 0}")
    spec = tmp_path / "limp.yaml"
    spec.write_text(text.replace("name: two_link", "name: limp"))
    out = tmp_path / "limp"
    assert main(["build", str(spec), "-o", str(out), "--no-compile", "-q"]) == 0
    program = tmp_path / "main.c"
    program.write_text('#include <math.h>\n#include <stdio.h>\n#include "limp.h"\n'
                       "int main(void) {\n"
                       "    double q[2] = {0.1, 0.2}, qd[2] = {0, 0}, tau[2] = {1, 1}, out[2] = {7, 7};\n"
                       "    int s = limp_forward_dynamics(q, qd, tau, out);\n"
                       '    printf("%d %g %g\\n", s, out[0], out[1]);\n'
                       "    qd[0] = NAN; out[0] = out[1] = 7;\n"
                       "    s = limp_forward_dynamics(q, qd, tau, out);\n"
                       '    printf("%d %g %g\\n", s, out[0], out[1]);\n'
                       "    return 0;\n}\n")
    exe = tmp_path / "main"
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", f"-I{out}", str(program), str(out / "limp.c"),
                    "-lm", "-o", str(exe)], check=True)
    lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split("\n")
    assert lines[0] == "2 0 0"  # not finite: zeroed
    assert lines[1] == "1 7 7"  # NaN input: nothing written
