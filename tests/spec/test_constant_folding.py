"""Constant parts of formulas are folded into one number at build time: one that cannot be
evaluated, or is not a finite real number, is the user's input, refused where it stands
(exit 1), never an internal error and never a NaN or infinite literal in the emitted C."""

from __future__ import annotations

import importlib
import math
import sys
import time

import mpmath
import numpy as np
import pytest

from robotgen.cli import main
from robotgen.errors import Location, UserError
from robotgen.model.expression import MATH_LIB, parse_constant, parse_expression

SPEC = 'robotgen: 1\nname: fx\nroot: a\nnodes: {a: {define: {formulas: {coordinates: [q], M: [["1 + %s"]]}}}}\n'
COLUMN = SPEC.splitlines()[3].index("%s") + 1  # where the constant starts on line 4


@pytest.mark.parametrize(
    "text, offset, words",
    [
        ("exp(1000)", 0, "(too large)"),
        ("10^400", 2, "'10^400' cannot be evaluated (too large)"),
        ("1/0", 1, "(division by zero)"),
        ("0/0", 1, "(division by zero)"),
        ("sqrt(-1)", 0, "outside the function's domain"),
        ("log(0)", 0, "outside the function's domain"),
        ("acos(2)", 0, "outside the function's domain"),
        ("1e308*10", 5, "is not a finite real number"),
        ("(-8)^(1/3)", 4, "is not a finite real number"),
        ("2*(q + 1/0)", 8, "'1/0'"),
    ],
)
def test_bad_constants_are_located_errors(tmp_path, capsys, text, offset, words):
    path = tmp_path / "f.yaml"
    path.write_text(SPEC % text)
    out = tmp_path / "out"
    assert main(["build", str(path), "-o", str(out), "--no-compile"]) == 1
    err = capsys.readouterr().err
    assert f"f.yaml:4:{COLUMN + offset}:" in err and words in err, err
    assert "internal error" not in err and not out.exists()


def test_constants_that_are_fine_stay_fine():
    loc = Location("x.yaml", 1, 1)
    assert parse_constant("pi/2", loc) == pytest.approx(1.5707963267948966)
    for text in ("q^1e300", "exp(q) / (1 + 0*q)", "2*pi + e", "0^0 + sign(0)", "atan2(0, 0)"):
        parse_expression(text, loc, {"q"})
    with pytest.raises(UserError, match="division by zero"):
        parse_constant("1/(2 - 2)", loc)
    with pytest.raises(UserError, match="too large"):  # a spec's numbers are SI values, at most 1e15
        parse_constant("1e300", loc)


@pytest.mark.parametrize("text, index", [("ｍ2 + 1", 0), ("sⅰn(q)", 1), ("2*ℯ", 2), ("q + é", 4)])
def test_unicode_look_alikes_are_refused_where_they_stand(text, index):
    with pytest.raises(UserError) as caught:
        parse_expression(text, Location("x.yaml", 3, 10), {"q", "m2"})
    assert (caught.value.location.line, caught.value.location.col) == (3, 10 + index)
    assert "is not allowed in an expression" in caught.value.message


def _reference(function: str, x: float) -> float:
    """The correctly rounded value: mpmath at 200 bits (its own reduction of a large argument
    works at the precision the argument's magnitude needs), rounded once to a double."""
    with mpmath.workprec(200):
        return float(getattr(mpmath, function)(mpmath.mpf(x)))


def _hard_arguments() -> list[float]:
    """Doubles nearest to multiples of pi/2 (their remainder is a few ulps of x, or for the
    worst double of all, 6381956970095103 * 2^797, 4.7e-19), and powers of two."""
    with mpmath.workprec(2000):
        near = [float(k * mpmath.pi / 2) for k in (*range(1, 200), *(7**j for j in range(20, 360, 17)))]
    return near + [6381956970095103 * 2.0**797, *(2.0**j for j in range(-1074, 1024, 37))]


@pytest.mark.parametrize("function", ["sin", "cos", "tan"])
def test_folded_trigonometric_constants_are_correctly_rounded_at_every_magnitude(function):
    """Against mpmath over 1e-300 to 1e300: the old 40-digit reduction by a 60-digit pi folded
    sin(1e40) to 0.9093 (0.6468) and sin(1e42) to -5.1e93."""
    rng = np.random.default_rng(7)
    magnitudes = 10.0 ** rng.uniform(-300, 300, 1500)
    xs = [float(v) for v in magnitudes * rng.choice([-1.0, 1.0], 1500)] + _hard_arguments()
    fold = MATH_LIB[function]
    wrong = [(x, fold(x), _reference(function, x)) for x in xs if fold(x) != _reference(function, x)]
    assert not wrong, wrong[:5]
    assert math.copysign(1, fold(-0.0)) == math.copysign(1, getattr(math, function)(-0.0))  # the sign of zero


@pytest.mark.parametrize(
    "function, x", [("sin", 1e40), ("sin", 1e42), ("cos", 1e300), ("tan", 2e46), ("tanh", 1e300), ("sin", -1e-300)]
)
def test_constant_fields_fold_to_the_correct_value(function, x):
    assert parse_constant(f"{function}({x!r})", Location("x.yaml", 1, 1)) == _reference(function, x)
    if (function, x) == ("sin", 1e40):
        assert _reference(function, x) == pytest.approx(0.6468, abs=1e-4)  # the value; 0.9093 was folded


def test_a_huge_angle_folds_in_milliseconds(tmp_path):
    """sin(2e46) took 6-47 s in the series on a mis-reduced argument."""
    path = tmp_path / "f.yaml"
    path.write_text(SPEC % "sin(2e46) * sin(3e307) * cos(q * 1e300)")
    start = time.perf_counter()
    assert main(["check", str(path)]) == 0
    assert time.perf_counter() - start < 5


def test_the_mass_check_sees_the_folded_value(tmp_path, capsys):
    """sin(1e300) = -0.818, so M = [[1 + sin(1e300) - 1]] is not positive definite, as the
    same number written out is not (the check once met an overflow there and skipped the
    sample). The emitted M holds the folded value itself."""
    path = tmp_path / "f.yaml"
    for text, status in (
        ("sin(1e300) - 1", 1),
        ("-1.8178819121159085", 1),
        ("(sin(1e300) - 1) * (1 + q^2)", 1),
        ("sin(1e40) + cos(q)^2", 0),
    ):
        path.write_text(SPEC % text)
        assert main(["check", str(path)]) == status, text
        assert ("M is not positive definite" in capsys.readouterr().err) == bool(status), text
    out = tmp_path / "out"
    assert main(["build", str(path), "-o", str(out), "-q"]) == 0
    sys.path.insert(0, str(out))
    try:
        fx = importlib.import_module("fx")
    finally:
        sys.path.remove(str(out))
    assert fx.mass(np.zeros(1)).ravel()[0] == 1 + _reference("sin", 1e40) + 1  # cos(0)^2 = 1 exactly


@pytest.mark.parametrize("text, column", [("1 # + q^2 - 5", 3), ("q#", 2), ("(1 + q) #comment", 9)])
def test_a_hash_inside_an_expression_is_an_error(text, column):
    """A quoted '#' reaches the expression parser, which read the rest as a comment:
    "1 # + q^2 - 5" was 1."""
    with pytest.raises(UserError) as caught:
        parse_expression(text, Location("x.yaml", 4, 10), {"q"})
    assert (caught.value.location.line, caught.value.location.col) == (4, 9 + column)
    assert "'#' is not allowed in an expression" in caught.value.message


def test_pi_for_the_reduction_is_right_to_its_last_bit():
    from robotgen.numeric.exact import _PI_BITS, _half_pi_scaled

    with mpmath.workprec(_PI_BITS + 100):
        exact_value = int(mpmath.floor(mpmath.pi / 2 * mpmath.mpf(2) ** _PI_BITS))
    assert abs(_half_pi_scaled(_PI_BITS) - exact_value) <= 1
