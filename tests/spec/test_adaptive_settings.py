"""The settings of law resolved_adaptive in a spec: the weight rule's Q, full Q and R
matrices, the identification's settings and payload changes; each wrong value is reported
where it stands (FILE:LINE:COL) with what is wrong."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system

RMAC = Path(__file__).resolve().parents[2] / "specs" / "puma560_rmac.yaml"
ANCHOR = "        tool: {xyz: [0, 0, 0.1], rpy: [0, pi/2, 0]}   # hand x along the tool: pitch 0 at the start\n"


def spec(tmp_path, settings: str = "", simulation: str | None = None) -> str:
    """puma560_rmac.yaml with ``settings`` lines added under resolved_adaptive (8 spaces in)
    and its payload_change line replaced by ``simulation``."""
    text = RMAC.read_text()
    assert ANCHOR in text
    text = text.replace(ANCHOR, ANCHOR + settings)
    if simulation is not None:
        line = "  payload_change: {at: 1.0, mass: 2.0}  # the hand picks up 2 kg at t = 1 s\n"
        assert line in text
        text = text.replace(line, simulation)
    path = tmp_path / "rmac.yaml"
    path.write_text(text)
    return str(path)


def line_of(text: str, fragment: str) -> int:
    return next(k + 1 for k, line in enumerate(text.splitlines()) if fragment in line)


def test_the_weight_rule_and_given_matrices(tmp_path):
    s = load_system(spec(tmp_path)).root_node.hand
    np.testing.assert_array_equal(s.q, np.repeat([2 * 20 / 0.001, 1.0], 6))  # Q = diag(2 sigma / T, 1)
    assert s.r is None and s.torque_weight == 1.0 and s.bandwidth == 20.0
    assert s.affine and s.directional and s.initial_covariance == (1.0, 1e-8, 1e-2)
    s = load_system(spec(tmp_path, "        bandwidth: 50\n        torque_weight: 3\n")).root_node.hand
    np.testing.assert_array_equal(s.q, np.repeat([1e5, 1.0], 6))
    assert s.torque_weight == 3.0
    L = np.tril(np.arange(1.0, 37.0).reshape(6, 6)) / 10 + np.eye(6)
    R = L @ L.T
    rows = "".join(f"          - [{', '.join(repr(float(v)) for v in row)}]\n" for row in R)
    s = load_system(
        spec(
            tmp_path,
            "        q: [1e5, 1e5, 1, 1]\n        r:\n"
            + rows
            + "        initial_covariance: {B: 1e-6}\n        affine: false\n",
        )
    ).root_node.hand
    np.testing.assert_array_equal(s.q, np.repeat([1e5, 1e5, 1, 1], 3))
    np.testing.assert_array_equal(s.r, R)
    assert s.bandwidth is None and s.initial_covariance == (1.0, 1e-6, 1e-2) and not s.affine
    names = [p.name for p in s.parameters("rmac")]
    assert names == ["rmac_q", "rmac_r", "rmac_forgetting"]
    assert s.parameters("rmac")[1].shape == (6, 6)


def matrix(key: str, M) -> str:
    """``key`` as a YAML matrix under resolved_adaptive, a row per line."""
    return f"        {key}:\n" + "".join(f"          - [{', '.join(f'{v:g}' for v in row)}]\n" for row in M)


NOT_PD = np.eye(6)
NOT_PD[0, 1] = NOT_PD[1, 0] = 2  # eigenvalues -1, 1, 1, 1, 1, 3


@pytest.mark.parametrize(
    "settings, fragment, message",
    [
        (matrix("q", np.eye(12)[:11]), "        q:", "Q as a matrix must be 12 x 12, got 11 rows"),
        (matrix("r", np.tril(np.ones((6, 6)))), "          - [1, 0, 0, 0, 0, 0]", "R must be symmetric"),
        (matrix("r", NOT_PD), "        r:", "R must be positive definite (eq 38): its smallest eigenvalue is -1"),
        (
            "        q: [1, 2, 3]\n",
            "        q:",
            "expected a number or 4 (position, orientation, velocity, angular "
            "velocity), 12 (the diagonal) or 12 rows of 12 entries, got 3",
        ),
        ("        r: [1, 1, 1, 1, 1, -1]\n", "        r:", "weight -1 must be positive"),
        ("        q: 1e5\n        bandwidth: 10\n", "        bandwidth:", "give q or bandwidth, not both"),
        (
            "        bandwidth: 3000\n",
            "        bandwidth:",
            "bandwidth 3000 rad/s is at or past 2 / period (2000 rad/s)",
        ),
        ("        forgetting: 1.5\n", "        forgetting:", "forgetting factor 1.5 must be in (0, 1] (eq 37)"),
        ("        forgetting: 0\n", "        forgetting:", "forgetting factor 0 must be in (0, 1] (eq 37)"),
        ("        torque_weight: -2\n", "        torque_weight:", "torque weight -2 must be positive"),
        (
            "        initial_covariance: {c: -1}\n",
            "        initial_covariance:",
            "is less than or equal to the minimum",
        ),
        ("        affine: maybe\n", "        affine:", "affine"),
    ],
)
def test_wrong_settings_are_located(tmp_path, settings, fragment, message):
    path = spec(tmp_path, settings)
    with pytest.raises(UserErrors) as caught:
        load_system(path)
    text = Path(path).read_text()
    errors = caught.value.errors
    assert any(message in e.message for e in errors), [e.message for e in errors]
    error = next(e for e in errors if message in e.message)
    assert error.location.line == line_of(text, fragment), (error.location, fragment)


def test_payload_changes(tmp_path):
    changes = load_system(
        spec(
            tmp_path,
            simulation="  payload_change:\n    - {at: 1.0, mass: 2.0}\n"
            "    - {at: 5, mass: 5, com: [0.05, 0.05, 0.03]}\n    - {at: 8, mass: 0}\n",
        )
    ).simulation.payload_changes
    assert [(c.at, c.mass, c.com) for c in changes] == [
        (1.0, 2.0, (0, 0, 0)),
        (5.0, 5.0, (0.05, 0.05, 0.03)),
        (8.0, 0.0, (0, 0, 0)),
    ]
    path = spec(tmp_path, simulation="  payload_change:\n    - {at: 5.0, mass: 2.0}\n    - {at: 2, mass: 1}\n")
    with pytest.raises(UserErrors) as caught:
        load_system(path)
    (error,) = caught.value.errors
    assert "payload changes must be in time order: 2 s comes after 5 s" in error.message
    assert error.location.line == line_of(Path(path).read_text(), "{at: 2, mass: 1}")
