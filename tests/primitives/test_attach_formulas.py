"""ATTACH with the user's own constraint formulas: the Styx box grasp written as h, h^-1
and G (StyxDefinitions.m's g, RobotInverse[g] and G, with the angle measured from the left
to the right fingertip) gives the same hand as the built-in planar_contacts constraint."""

from __future__ import annotations

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

FORMULAS = """        formulas:
          coordinates: [x, y, psi]
          parameters: {r: 0.05}
          h: ["(xl + xr)/2", "(yl + yr)/2", "atan2(yr - yl, xr - xl)"]
          h_inverse: ["x - r*cos(psi)", "y - r*sin(psi)", "x + r*cos(psi)", "y + r*sin(psi)"]
          G: [[1, 0, 1, 0], [0, 1, 0, 1],
              ["r*sin(psi)", "-r*cos(psi)", "-r*sin(psi)", "r*cos(psi)"]]
"""


def test_formula_grasp_equals_planar_contacts(tmp_path, build_module):
    text = (ROOT / "specs" / "styx_high_ct.yaml").read_text()
    line = "        planar_contacts: {points: [[-0.05, 0], [0.05, 0]]}   # (-r, 0), (r, 0), r = 0.05 m\n"
    assert line in text
    spec = tmp_path / "styx_formula_grasp.yaml"
    spec.write_text(text.replace(line, FORMULAS).replace("name: styx_high_ct", "name: styx_formula_grasp"))
    builtin = build_module(ROOT / "specs" / "styx_high_ct.yaml")
    formula = build_module(spec)
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = np.array([0.0, 0.12, 0.0]) + rng.normal(size=3) * [0.01, 0.01, 0.2]
        theta = builtin.plant_inverse(x)
        np.testing.assert_allclose(formula.plant_inverse(x), theta, atol=1e-12)
        xd = rng.normal(size=3)
        theta_dot = builtin.plant_dynamics(theta, xd, np.zeros(4))[0]
        for fn in ("hand_mass", "hand_n"):
            args = (theta,) if fn == "hand_mass" else (theta, theta_dot)
            np.testing.assert_allclose(getattr(formula, fn)(*args), getattr(builtin, fn)(*args), atol=1e-12)
        np.testing.assert_allclose(
            formula.hand_coriolis(theta, theta_dot), builtin.hand_coriolis(theta, theta_dot), atol=1e-12
        )
        x_f, xd_f = formula.hand_read(theta, theta_dot)
        np.testing.assert_allclose(x_f, x, atol=1e-12)
        np.testing.assert_allclose(xd_f, xd, atol=1e-10)
        f_e, f_i = rng.normal(size=3), rng.normal(size=1)
        tau_b = builtin.hand_write(theta, theta_dot, x, xd, np.zeros(3), f_e, f_i)
        tau_f = formula.hand_write(theta, theta_dot, x, xd, np.zeros(3), f_e, np.zeros(1))
        tau_b0 = builtin.hand_write(theta, theta_dot, x, xd, np.zeros(3), f_e, np.zeros(1))
        np.testing.assert_allclose(tau_f, tau_b0, atol=1e-12)  # the external force part
        assert np.abs(tau_b - tau_b0).max() > 1e-6  # and the squeeze is really another direction
