"""Builds are the same on every machine: the constants robotgen prints into C are computed
without BLAS, LAPACK or libm (robotgen.numeric.exact, robotgen.numeric.riccati), and are
correctly rounded. The generated-output test (test_golden.py) is run by CI under several
OPENBLAS_CORETYPE values and with the lowest numpy/scipy allowed; here the pieces are
checked against independent references."""

from __future__ import annotations

import math
import os
import random
import subprocess
import sys
from decimal import Decimal, localcontext
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from robotgen.frontend import load_system
from robotgen.numeric import exact
from robotgen.numeric.riccati import RiccatiError, gain, solve_care
from robotgen.symbolic.root_laws.resolved_rate.regulator import linearise

ROOT = Path(__file__).resolve().parents[2]


def correctly_rounded(f, *args: float) -> float:
    """f at 80 digits (twice exact's working precision), rounded once to a double."""
    saved = exact._DIGITS
    exact._DIGITS = 80
    try:
        return f(*args)
    finally:
        exact._DIGITS = saved


@pytest.mark.parametrize("name", ["sin", "cos", "tan", "atan", "exp", "tanh", "sinh", "cosh"])
def test_elementary_functions_are_correctly_rounded(name):
    """At 40 digits the result equals the 80-digit result rounded to a double (the value
    no libm can beat), and it is within libm's documented error (glibc: 2 ulp for the
    hyperbolic functions, 1 for the others) of libm's."""
    f = getattr(exact, name)
    rng = random.Random(7)
    for _ in range(300):
        x = rng.uniform(-4, 4) if name not in ("tan",) else rng.uniform(-1.5, 1.5)
        value = f(x)
        assert value == correctly_rounded(f, x), (name, x)
        libm_ulps = 2 if name in ("tanh", "sinh", "cosh") else 1
        assert abs(value - getattr(math, name)(x)) <= libm_ulps * math.ulp(value), (name, x)


def test_two_argument_and_domain_functions():
    rng = random.Random(3)
    for _ in range(300):
        y, x = rng.uniform(-3, 3), rng.uniform(-3, 3)
        assert abs(exact.atan2(y, x) - math.atan2(y, x)) <= math.ulp(math.atan2(y, x))
        u = rng.uniform(-1, 1)
        assert abs(exact.asin(u) - math.asin(u)) <= math.ulp(math.asin(u))
        assert abs(exact.acos(u) - math.acos(u)) <= math.ulp(math.acos(u))
        a = rng.uniform(0.01, 4)
        assert abs(exact.log(a) - math.log(a)) <= math.ulp(math.log(a))
        assert abs(exact.power(a, y) - a**y) <= 2 * math.ulp(a**y)
    assert exact.atan2(0.0, -1.0) == math.pi and exact.cos(math.pi / 2) == 6.123233995736766e-17
    assert exact.power(0.1, 2.0) == 0.1 * 0.1 and exact.power(2.0, -3.0) == 0.125
    for f, x in ((exact.log, 0.0), (exact.asin, 1.5), (exact.acos, -2.0)):
        with pytest.raises(ValueError):
            f(x)


def test_products_are_exact_then_rounded_once():
    """Each entry of exact.matmul is the rational product of the doubles, rounded once;
    numpy's BLAS product of the same matrices differs from it in some entry (so the
    reference can tell the two apart)."""
    rng = np.random.default_rng(5)
    differs = False
    for _ in range(50):
        A, B, C = rng.normal(size=(4, 4)), rng.normal(size=(4, 4)), rng.normal(size=(4, 3))
        product = exact.matmul(A, B)
        for i in range(4):
            for j in range(4):
                ref = float(sum((Fraction(A[i, k]) * Fraction(B[k, j]) for k in range(4)), Fraction(0)))
                assert product[i, j] == ref
        differs |= bool(np.any(product != A @ B))
        three = exact.matmul(A, B, C)
        assert np.array_equal(three, exact.matmul(exact.matmul(A, B), C))
        v = rng.normal(size=3)
        assert exact.matmul(C, v).shape == (4,)
        assert exact.norm(v) == math.sqrt(float(sum(Fraction(x) ** 2 for x in v)))
    assert differs


def test_parallel_axis_is_exact():
    I, m, d = np.diag([0.1, 0.2, 0.3]), 1.7, np.array([0.1, -0.2, 0.05])
    out = exact.parallel_axis(I, m, d)
    dd = sum(Fraction(x) ** 2 for x in d)
    for i in range(3):
        for j in range(3):
            ref = Fraction(I[i, j]) + Fraction(m) * ((dd if i == j else 0) - Fraction(d[i]) * Fraction(d[j]))
            assert out[i, j] == float(ref)


def _puma_regulator():
    system = load_system(str(ROOT / "specs" / "puma560_rmrc.yaml"))
    node = system.root_node
    model = linearise(system.nodes[node.robot].leaf, node.rate.lqr.nominal)
    return model, np.diag(node.rate.lqr.q_weights), np.diag(node.rate.lqr.r_weights)


def test_riccati_matches_scipy_on_the_stiff_puma_regulator():
    """The PUMA 560 regulator (eigenvalues of A from -782 to -0.004): the solution agrees
    with scipy's to 1e-9 and its residual is smaller than scipy's."""
    model, Q, R = _puma_regulator()
    P = solve_care(model.A, model.B, Q, R)
    reference = solve_continuous_are(model.A, model.B, Q, R)

    def residual(X):
        return np.abs(model.A.T @ X + X @ model.A - X @ model.B @ np.linalg.solve(R, model.B.T) @ X + Q).max()

    print(
        f"\n  PUMA regulator: |P - P_scipy| / |P| = {np.abs(P - reference).max() / np.abs(reference).max():.2e}, "
        f"residual {residual(P):.2e} (scipy {residual(reference):.2e})"
    )
    np.testing.assert_allclose(P, reference, rtol=0, atol=1e-9 * np.abs(reference).max())
    assert residual(P) <= residual(reference)
    np.testing.assert_array_equal(P, P.T)
    K = gain(model.B, R, P)
    assert np.linalg.eigvals(model.A - model.B @ K).real.max() < 0


def test_riccati_on_random_systems_and_an_unstabilisable_one():
    rng = np.random.default_rng(11)
    for n, m in ((2, 1), (4, 2), (6, 3)):
        A = rng.normal(size=(n, n))
        B = rng.normal(size=(n, m))
        Q = np.eye(n) * rng.uniform(0.5, 5)
        R = np.diag(rng.uniform(0.1, 2, size=m))
        np.testing.assert_allclose(solve_care(A, B, Q, R), solve_continuous_are(A, B, Q, R), rtol=1e-9, atol=1e-9)
    # an unstable mode that no input reaches has no stabilising solution
    A = np.diag([1.0, -1.0])
    B = np.array([[0.0], [1.0]])
    with pytest.raises(RiccatiError):
        solve_care(A, B, np.eye(2), np.eye(1))


def _build_under(coretype: str, spec: Path, out: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, OPENBLAS_CORETYPE=coretype)
    return subprocess.run(
        [sys.executable, "-m", "robotgen", "build", str(spec), "-o", str(out), "--no-compile", "-q"],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )


def coretypes() -> list[str]:
    """OpenBLAS kernels this CPU can run, newest first (SkylakeX needs AVX-512)."""
    flags = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    kinds = []
    if "avx512f" in flags:
        kinds.append("SkylakeX")
    if "avx2" in flags:
        kinds.append("Haswell")
    if " avx " in flags:
        kinds.append("Sandybridge")
    kinds.append("Nehalem")
    return kinds


def test_stiff_builds_agree_across_blas_kernels(tmp_path):
    """The two specs whose constants BLAS used to change (DH inertias, Riccati gains) build
    to the same bytes under every OpenBLAS kernel this CPU runs."""
    kinds = coretypes()
    assert len(kinds) >= 2
    for spec in ("stanford", "puma560_rmrc"):
        texts = set()
        for kind in kinds:
            out = tmp_path / f"{spec}-{kind}"
            r = _build_under(kind, ROOT / "specs" / f"{spec}.yaml", out)
            assert r.returncode == 0, r.stderr
            texts.add((out / f"{spec}.c").read_bytes() + (out / "manifest.json").read_bytes())
        assert len(texts) == 1, f"{spec} differs between OpenBLAS kernels {kinds}"


def test_decimal_reference_digits():
    """exact's pi, for argument reduction, is pi to 60 digits (checked by Machin's formula)."""
    with localcontext() as ctx:
        ctx.prec = 70

        def arctan_inv(k: int) -> Decimal:
            x, total, term, n = Decimal(1) / k, Decimal(0), Decimal(1) / k, 1
            while term != 0:
                total += term / n if (n // 2) % 2 == 0 else -term / n
                term *= x * x
                n += 2
            return total

        pi = 16 * arctan_inv(5) - 4 * arctan_inv(239)
        assert abs(pi - exact._PI) < Decimal(10) ** -58
