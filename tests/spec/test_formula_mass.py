"""A formulas leaf's M must be an inertia matrix: symmetric and positive definite, checked
at sample configurations when the spec is read (forward dynamics' Cholesky factorisation
reads one triangle, and fails where M is not positive definite)."""

from __future__ import annotations

import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system

SPEC = (
    "robotgen: 1\nname: fm\nroot: a\nnodes:\n  a:\n    define:\n      formulas:\n        coordinates: [q1, q2]\n"
    "        M: {}\n"
)


@pytest.mark.parametrize(
    "M, col, words",
    [
        ("[[1, 0], [0, -1]]", 9, "not positive definite at q1 = 0, q2 = 0 (smallest eigenvalue -1)"),
        ("[[0, 0], [0, 0]]", 9, "not positive definite"),
        ("[[1, 5], [0, 1]]", 22, "M[1][0] = 0 but M[0][1] = 5"),
        ('[["cos(q1)", 0], [0, 1]]', 9, "not positive definite at q1 = "),
    ],
)
def test_not_an_inertia_matrix(tmp_path, M, col, words):
    path = tmp_path / "m.yaml"
    path.write_text(SPEC.format(M))
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    (error,) = caught.value.errors
    assert (error.location.line, error.location.col) == (9, col) and words in error.message, str(error)


def test_an_inertia_matrix_passes(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(SPEC.format('[["1 + q1^2", "0.1*cos(q2)"], ["0.1*cos(q2)", 2]]'))
    assert load_system(str(path)).root == "a"
