"""The double kernels' own sin and cos (robotgen.emit.sincos): within the documented bound of
a higher-precision reference over the whole reduced range, libm's answer past it, and the
program rewrite (angles first, one SINCOS step) computing what the graph computes."""

from __future__ import annotations

import importlib.util
import shutil

import casadi as ca
import numpy as np
import pytest

from robotgen.emit import build, sincos
from robotgen.emit import compile as emit_compile
from robotgen.emit.sx_program import read_program
from robotgen.symbolic.kernel import make_kernel

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is required")
BOUND = 2.3e-16  # the module docstring's and docs/c-api.md's
N = 7  # odd: the last pair is padded


def _angles_kernel():
    x = ca.SX.sym("x", N)
    return make_kernel(
        "angles", "sin and cos of each x", [("x", x)], [("s", ca.sin(x), (N, 1)), ("c", ca.cos(x), (N, 1))]
    )


def _mixed_kernel():
    """An offset angle, a product, an angle computed late, a sin of a sin (libm), one sin alone."""
    x = ca.SX.sym("x", 3)
    late = x[0] * x[1] + ca.exp(x[2])
    out = ca.vertcat(
        ca.sin(x[0] + 0.3) * ca.cos(x[1]), ca.cos(ca.sin(x[2])), ca.sin(late) - ca.cos(late), ca.sin(x[1] - x[0])
    )
    return make_kernel("mixed", "a mix", [("x", x)], [("y", out, (4, 1))])


def _load(directory, name):
    spec = importlib.util.spec_from_file_location(name, directory / (name + emit_compile.extension_suffix()))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("sincos") / "trig"
    build.emit(out, "trig", [_angles_kernel(), _mixed_kernel()], nq=1, spec_sha256="ab" * 32)
    return out, _load(out, "trig")


def _reference(x):
    """sin and cos in extended precision where the platform has it (x86: 64-bit mantissa)."""
    wide = np.asarray(x, dtype=np.longdouble)
    return np.sin(wide), np.cos(wide)


def _sample():
    rng = np.random.default_rng(11)
    quarter = np.pi / 4
    k = np.arange(-4000, 4000)
    return np.concatenate(
        [
            rng.uniform(-2 * np.pi, 2 * np.pi, 200_000),
            rng.uniform(-1e5, 1e5, 100_000),
            k * quarter,
            np.nextafter(k * quarter, np.inf),
            np.nextafter(k * quarter, -np.inf),  # at the reduction's edges
            k * (np.pi / 2),
            np.linspace(-1e-3, 1e-3, 2001),
            [1e-300, 5e-324, 1e5, -1e5],
        ]
    )


def test_error_within_the_documented_bound(built):
    if np.finfo(np.longdouble).nmant < 60:
        pytest.skip("no extended-precision long double for the reference")
    _, module = built
    x = _sample()
    x = x[: len(x) - len(x) % N].reshape(-1, N)
    s, c = module.angles(x)
    rs, rc = _reference(x)
    assert float(np.max(np.abs(s - rs))) <= BOUND
    assert float(np.max(np.abs(c - rc))) <= BOUND
    assert np.all(np.abs(s) <= 1) and np.all(np.abs(c) <= 1)


def test_beyond_the_reduced_range_it_is_libm(built):
    _, module = built
    x = np.array([1e5 * (1 + 1e-15), -3e7, 1e300, np.inf, -np.inf, np.nan, 2.0])
    s, c = module.angles(x)
    with np.errstate(invalid="ignore"):
        expected_s, expected_c = np.sin(x), np.cos(x)
    finite = np.isfinite(x)
    np.testing.assert_allclose(s[finite], expected_s[finite], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c[finite], expected_c[finite], rtol=0, atol=1e-15)
    assert np.all(np.isnan(s[~finite])) and np.all(np.isnan(c[~finite]))


def test_rewritten_program_computes_the_graph(built):
    _, module = built
    kernel = _mixed_kernel()
    rng = np.random.default_rng(5)
    for x in rng.uniform(-4, 4, (200, 3)):
        np.testing.assert_allclose(module.mixed(x), np.ravel(np.array(kernel.function(x))), rtol=0, atol=4e-15)


def test_angles_come_first_and_only_nested_trig_keeps_libm(built):
    out, _ = built
    program = sincos.pair_angles(read_program(_mixed_kernel()))
    ops = [step.op for step in program.instructions]
    first = ops.index(sincos.SINCOS)
    assert ops.count(sincos.SINCOS) == 1
    assert sincos.SIN_LANE not in ops[:first] and ca.OP_SIN not in ops[:first]
    # x0 + 0.3, x1, the late angle, x1 - x0 and x2 (under the nested cos) are lanes; cos(sin(x2)) is libm
    assert len(program.instructions[first].args) == 5
    assert ops.count(ca.OP_COS) == 1 and ops.count(ca.OP_SIN) == 0
    source = (out / "trig.c").read_text()
    assert source.count(f"static void {sincos.HELPER}(") == 1
    assert "cos(w" in source and "sin(w" not in source


FLOAT_BOUND = 1.0e-7  # the module docstring's for float


@pytest.fixture(scope="module")
def built_float(tmp_path_factory):
    out = tmp_path_factory.mktemp("sincosf") / "trigf"
    build.emit(out, "trigf", [_angles_kernel()], nq=1, spec_sha256="ab" * 32, precision="float")
    return out, _load(out, "trigf")


def test_float_kernels_have_their_own_routine_within_its_bound(built_float):
    """The float rg_sincos2 against sin and cos of the float angle in double: within 1.0e-7 up to
    |x| = 4096 (the reduction's edges included), sinf and cosf past it."""
    out, module = built_float
    source = (out / "trigf.c").read_text()
    assert f"static void {sincos.HELPER}(const float *x" in source and "sinf(x[l])" in source
    x = np.concatenate([_sample()[:300_000], np.random.default_rng(3).uniform(-4096, 4096, 100_000)])
    x = np.clip(x, -4096, 4096).astype(np.float32)
    x = x[: len(x) - len(x) % N].reshape(-1, N)
    s, c = module.angles(x)
    assert np.array_equal(s.astype(np.float32), s)  # float results, as float64 arrays
    wide = x.astype(np.float64)
    assert float(np.max(np.abs(s - np.sin(wide)))) <= FLOAT_BOUND
    assert float(np.max(np.abs(c - np.cos(wide)))) <= FLOAT_BOUND
    far = np.array([4096.0005, -3e7, 1e30, np.inf, -np.inf, np.nan, 2.0], dtype=np.float32)
    s, c = module.angles(far)
    finite = np.isfinite(far)
    np.testing.assert_allclose(s[finite], np.sin(far.astype(np.float64))[finite], rtol=0, atol=6e-8)
    assert np.all(np.isnan(s[~finite])) and np.all(np.isnan(c[~finite]))


@pytest.mark.parametrize("real", ["double", "float"])
def test_polynomials_within_their_bounds_and_pi_splits_exactly(real):
    """pi/2's first two parts have the routine's bits (n times them exact for every n of the
    bound), and the polynomials, in exact arithmetic, against sin and cos of long double on
    [-pi/4, pi/4]: double's within 2^-57 (fdlibm's), float's within 2^-27 (sin relative to r,
    cos absolute)."""
    from fractions import Fraction

    t = sincos.ROUTINES[real]
    p1, p2, p3 = t.parts
    assert p1 + p2 + p3 == sincos._PI / 2
    n = int(t.above * 2 / np.pi) + 1
    for part in (p1, p2):
        assert float(part) == part and (part * 2**80).denominator == 1
        mantissa = int(part * 2**80)
        assert mantissa.bit_length() - (len(bin(mantissa)) - len(bin(mantissa).rstrip("0"))) <= t.bits
    assert n < 2 ** (53 - t.bits if real == "double" else 24 - t.bits)
    assert t.offset > t.above * 2 / np.pi + 1
    r = np.linspace(-np.pi / 4, np.pi / 4, 2001, dtype=np.longdouble)
    z = r * r
    value = float if real == "double" else (lambda c: float(np.float32(float(c))))
    ps = sum(np.longdouble(value(c)) * z**k for k, c in enumerate(t.sin_terms))
    pc = sum(np.longdouble(value(c)) * z**k for k, c in enumerate(t.cos_terms))
    bound = 2.0**-57 if real == "double" else 2.0**-27
    if np.finfo(np.longdouble).nmant >= 60:
        assert float(np.max(np.abs((r + r * z * ps - np.sin(r)) / np.where(r == 0, 1, r)))) <= bound
        assert float(np.max(np.abs(1 + z * pc - np.cos(r)))) <= bound
    assert Fraction(t.cos_terms[0]) == Fraction(-1, 2)
