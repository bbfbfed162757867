"""Constant parts of formulas are folded into one number at build time: one that cannot be
evaluated, or is not a finite real number, is the user's input, refused where it stands
(exit 1), never an internal error and never a NaN or infinite literal in the emitted C."""
from __future__ import annotations

import pytest

from robotgen.cli import main
from robotgen.errors import Location, UserError
from robotgen.model.expression import parse_constant, parse_expression

SPEC = 'robotgen: 1\nname: fx\nroot: a\nnodes: {a: {define: {formulas: {coordinates: [q], M: [["1 + %s"]]}}}}\n'
COLUMN = SPEC.splitlines()[3].index("%s") + 1  # where the constant starts on line 4


@pytest.mark.parametrize("text, offset, words", [
    ("exp(1000)", 0, "(too large)"), ("10^400", 2, "'10^400' cannot be evaluated (too large)"),
    ("1/0", 1, "(division by zero)"), ("0/0", 1, "(division by zero)"),
    ("sqrt(-1)", 0, "outside the function's domain"), ("log(0)", 0, "outside the function's domain"),
    ("acos(2)", 0, "outside the function's domain"), ("1e308*10", 5, "is not a finite real number"),
    ("(-8)^(1/3)", 4, "is not a finite real number"), ("2*(q + 1/0)", 8, "'1/0'"),
])
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
    with pytest.raises(UserError, match="too large"):  # 1e300 rad would defeat exact angle reduction
        parse_constant("1e300", loc)


@pytest.mark.parametrize("text, index", [("ｍ2 + 1", 0), ("sⅰn(q)", 1), ("2*ℯ", 2), ("q + é", 4)])
def test_unicode_look_alikes_are_refused_where_they_stand(text, index):
    with pytest.raises(UserError) as caught:
        parse_expression(text, Location("x.yaml", 3, 10), {"q", "m2"})
    assert (caught.value.location.line, caught.value.location.col) == (3, 10 + index)
    assert "is not allowed in an expression" in caught.value.message
