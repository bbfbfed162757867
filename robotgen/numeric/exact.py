"""Build-time arithmetic on the constants that robotgen prints into C, reproducible to the bit.

numpy's matrix products go to whichever BLAS kernel the CPU selects (fused multiply-adds or
not, other summation orders), and libm and numpy pick sin/cos/atan2 variants by CPU feature,
so the last bits of a DH placement or a merged inertia could differ between two machines
and show in the emitted C. Every constant of the model is therefore computed here instead:

- products and sums of matrices: each entry is the exact dot product (rational arithmetic on
  the doubles) rounded once to the nearest double;
- sin, cos, tan, atan2, exp, log and the other functions a spec's constant expressions may
  use: evaluated in 40-digit decimal arithmetic (sin, cos and tan in 50, after an exact
  reduction of the argument by pi/2: any double, up to 1.8e308) and rounded once to the
  nearest double;
- sqrt: IEEE 754 rounds it correctly on every machine.

So each result is the correctly rounded value of its exact definition, the same on every
machine and with every numpy, and no BLAS or libm call can change it.
"""

from __future__ import annotations

import math
from decimal import Decimal, DefaultContext, Overflow, localcontext
from fractions import Fraction
from functools import cache, lru_cache

import numpy as np

_DIGITS = 40
_TRIG_DIGITS = 50
# pi to 60 digits, for atan2's quadrants
_PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494")
# Bits of pi/2 for the reduction of sin's and cos's argument: a double is below 2^1024, so k,
# the nearest multiple of pi/2, has at most 1024 bits, and k times pi/2's error of 2^-_PI_BITS
# leaves the remainder r = x - k pi/2 an absolute error below 2^(1024 - _PI_BITS) = 2^-376. The
# remainder of a double is never below 2^-62 (the closest double to a multiple of pi/2,
# 6381956970095103 * 2^797, leaves 4.7e-19: Muller, Elementary Functions, ch. 11), so r keeps
# more than 300 correct bits whatever the double.
_PI_BITS = 1400


def _exact_sum(products) -> float:
    return float(sum(products, Fraction(0)))


def dot(a, b) -> float:
    """sum_i a_i b_i, exact and rounded once."""
    return _exact_sum(Fraction(float(x)) * Fraction(float(y)) for x, y in zip(a, b, strict=True))


def matmul(*factors) -> np.ndarray:
    """The product of matrices (or a matrix and a vector, last), left to right; each
    pairwise product is exact and rounded once per entry."""
    out = np.asarray(factors[0], dtype=float)
    for factor in factors[1:]:
        B = np.asarray(factor, dtype=float)
        vector = B.ndim == 1
        B2 = B.reshape(-1, 1) if vector else B
        C = np.array([[dot(row, col) for col in B2.T] for row in out])
        out = C.ravel() if vector else C
    return out


def norm(v) -> float:
    """|v|, the Euclidean norm of a vector from an exact dot product (sqrt correctly rounded)."""
    return math.sqrt(dot(v, v))


def unit(v) -> np.ndarray:
    """v / |v|: (3,) unit vector along v, each entry the exact quotient rounded once."""
    v = np.asarray(v, dtype=float)
    n = norm(v)
    return np.array([float(Fraction(float(x)) / Fraction(n)) for x in v])


def cross(a, b) -> np.ndarray:
    """a x b for (3,) vectors, each entry an exact two-term dot product rounded once."""
    return np.array(
        [dot((a[1], -a[2]), (b[2], b[1])), dot((a[2], -a[0]), (b[0], b[2])), dot((a[0], -a[1]), (b[1], b[0]))]
    )


def outer(a, b) -> np.ndarray:
    """a b^T: the (len(a), len(b)) outer product, each entry exact and rounded once."""
    return np.array([[float(Fraction(float(x)) * Fraction(float(y))) for y in b] for x in a])


def add(*terms) -> np.ndarray:
    """The exact sum of arrays (and scalars times arrays, as (s, A) pairs), rounded once."""

    def fractions(term):
        if isinstance(term, tuple):
            s, A = term
            return np.vectorize(lambda x: Fraction(float(s)) * Fraction(float(x)), otypes=[object])(A)
        return np.vectorize(lambda x: Fraction(float(x)), otypes=[object])(np.asarray(term, dtype=float))

    total = sum((fractions(t) for t in terms[1:]), fractions(terms[0]))
    return np.vectorize(float, otypes=[float])(total)


# -- elementary functions, correctly rounded ------------------------------------------------
def _dec(x: float) -> Decimal:
    return Decimal(float(x))


@cache
def _half_pi_scaled(bits: int) -> int:
    """floor(pi/2 * 2^bits) to within one unit, in integer arithmetic: Machin's formula
    pi = 16 atan(1/5) - 4 atan(1/239), each atan by its alternating series on integers with
    32 guard bits (every term is truncated, so the sum is off by at most its number of terms)."""
    guard = 32
    one = 1 << (bits + guard)

    def atan_inverse(n: int) -> int:  # atan(1/n) * one
        total, power, k, sign = 0, one // n, 1, 1
        while power:
            total += sign * (power // k)
            power //= n * n
            k, sign = k + 2, -sign
        return total

    return (8 * atan_inverse(5) - 2 * atan_inverse(239)) >> guard


def _reduced(x: float) -> tuple[Decimal, int]:
    """(r, k mod 4) with x = k pi/2 + r, |r| <= pi/4 (up to the rounding of a tie), r to
    _TRIG_DIGITS digits: the rational value of the double x in fixed point with _PI_BITS
    fraction bits (exact: a double's fraction has at most 1074 bits), less k times pi/2 in the
    same fixed point (Payne and Hanek's reduction, here in Python's integers)."""
    numerator, denominator = float(x).as_integer_ratio()  # denominator a power of two, at most 2^1074
    X = (numerator << _PI_BITS) // denominator  # exact
    H = _half_pi_scaled(_PI_BITS)
    k = (2 * X + H) // (2 * H)  # nearest integer to X / H
    return Decimal(X - k * H) / Decimal(1 << _PI_BITS), k % 4


def _sin_cos_dec(x: float) -> tuple[Decimal, Decimal]:
    """sin and cos of the double x: exact reduction to [-pi/4, pi/4] and Taylor series, in the
    caller's decimal context."""
    r, quadrant = _reduced(x)
    r2 = r * r
    s, term, n = r, r, 1
    while True:
        term = -term * r2 / ((n + 1) * (n + 2))
        n += 2
        if term == 0 or abs(term) < Decimal(10) ** (-2 * _TRIG_DIGITS):
            break
        s += term
    c, term, n = Decimal(1), Decimal(1), 0
    while True:
        term = -term * r2 / ((n + 1) * (n + 2))
        n += 2
        if term == 0 or abs(term) < Decimal(10) ** (-2 * _TRIG_DIGITS):
            break
        c += term
    return [(s, c), (c, -s), (-s, -c), (-c, s)][quadrant]


def _atan_dec(x: Decimal) -> Decimal:
    """atan by halving the argument (atan x = 2 atan(x / (1 + sqrt(1 + x^2)))) then Taylor."""
    halvings = 0
    while abs(x) > Decimal("0.1"):
        x = x / (1 + (1 + x * x).sqrt())
        halvings += 1
    x2, term, s, n = x * x, x, x, 1
    while True:
        term = -term * x2
        n += 2
        t = term / n
        if t == 0 or abs(t) < Decimal(10) ** (-2 * _DIGITS):
            break
        s += t
    return s * (2**halvings)


def _atan2_dec(y: Decimal, x: Decimal) -> Decimal:
    if x > 0:
        return _atan_dec(y / x)
    if x < 0:
        return _atan_dec(y / x) + (_PI if y >= 0 else -_PI)
    if y > 0:
        return _PI / 2
    if y < 0:
        return -_PI / 2
    return Decimal(0)


def _cached(function):
    """``function`` of doubles, cached by each double's value and sign: a spec repeats its
    constants. (An lru_cache alone would answer f(-0.0) with f(0.0), the two being equal.)"""

    @lru_cache(maxsize=4096)
    def by_key(key: tuple[tuple[float, float], ...]) -> float:
        return function(*(value for value, _ in key))

    def f(*args: float) -> float:
        return by_key(tuple((a, math.copysign(1.0, a)) for a in map(float, args)))

    f.__name__ = function.__name__
    return f


def _rounded(compute, digits: int = _DIGITS):
    """``compute`` on the exact decimal values of its double arguments in a context of
    ``digits`` digits (rounding half to even, whatever the caller's context), rounded once
    to a double; a result past the decimal exponent range is an OverflowError, as the math
    module's."""

    def f(*args: float) -> float:
        with localcontext(DefaultContext) as ctx:
            ctx.prec = digits
            try:
                return float(compute(*(_dec(a) for a in args)))
            except Overflow:
                raise OverflowError(f"{compute.__name__}: result too large") from None

    f.__name__ = compute.__name__
    return _cached(f)


def _trig(compute):
    """sin, cos or tan of a double, correctly rounded (``compute`` takes sin and cos of it)."""

    def f(x: float) -> float:
        if not math.isfinite(x):
            raise ValueError(f"math domain error in {compute.__name__}")
        if x == 0 and compute.__name__ != "cos":
            return x  # sin(-0.0) and tan(-0.0) are -0.0, as IEEE 754 has them
        with localcontext(DefaultContext) as ctx:
            ctx.prec = _TRIG_DIGITS
            return float(compute(*_sin_cos_dec(x)))

    f.__name__ = compute.__name__
    return _cached(f)


def _check_domain(ok: bool, name: str) -> None:
    if not ok:
        raise ValueError(f"math domain error in {name}")


@_trig
def sin(s: Decimal, c: Decimal) -> Decimal:
    """sin x, correctly rounded; the decorator reduces x by pi/2 exactly and passes sin and cos of it as (s, c)."""
    return s


@_trig
def cos(s: Decimal, c: Decimal) -> Decimal:
    """cos x, correctly rounded; the decorator passes sin and cos of x as (s, c)."""
    return c


@_trig
def tan(s: Decimal, c: Decimal) -> Decimal:
    """tan x = s / c, correctly rounded; the decorator passes sin and cos of x as (s, c)."""
    return s / c


@_rounded
def atan(x: Decimal) -> Decimal:
    """atan x [rad] in (-pi/2, pi/2), correctly rounded."""
    return _atan_dec(x)


@_rounded
def atan2(y: Decimal, x: Decimal) -> Decimal:
    """atan2(y, x) [rad] in [-pi, pi], the quadrant from the signs of y and x, correctly rounded."""
    return _atan2_dec(y, x)


@_rounded
def asin(x: Decimal) -> Decimal:
    """asin x [rad] for |x| <= 1 (else a math domain error), as atan2(x, sqrt(1 - x^2)), correctly rounded."""
    _check_domain(abs(x) <= 1, "asin")
    return _atan2_dec(x, (1 - x * x).sqrt())


@_rounded
def acos(x: Decimal) -> Decimal:
    """acos x [rad] for |x| <= 1 (else a math domain error), as atan2(sqrt(1 - x^2), x), correctly rounded."""
    _check_domain(abs(x) <= 1, "acos")
    return _atan2_dec((1 - x * x).sqrt(), x)


@_rounded
def exp(x: Decimal) -> Decimal:
    """e^x, correctly rounded; an OverflowError past the double range."""
    return x.exp()


@_rounded
def log(x: Decimal) -> Decimal:
    """The natural logarithm of x > 0 (else a math domain error), correctly rounded."""
    _check_domain(x > 0, "log")
    return x.ln()


@_rounded
def sinh(x: Decimal) -> Decimal:
    """sinh x = (e^x - e^-x) / 2, correctly rounded."""
    return (x.exp() - (-x).exp()) / 2


@_rounded
def cosh(x: Decimal) -> Decimal:
    """cosh x = (e^x + e^-x) / 2, correctly rounded."""
    return (x.exp() + (-x).exp()) / 2


@_rounded
def tanh(x: Decimal) -> Decimal:
    """tanh x, from e^(-2|x|) so that no x overflows, correctly rounded."""
    e = (-2 * abs(x)).exp()  # at most 1: no overflow for any x (tanh(1e300) is 1)
    return (1 - e) / (1 + e) * (1 if x >= 0 else -1)


@_rounded
def power(x: Decimal, y: Decimal) -> Decimal:
    """x^y, correctly rounded: an integral y by exact powers (0^y needs y >= 0), else x > 0 (or x = 0, y > 0)."""
    if y == y.to_integral_value():
        _check_domain(x != 0 or y >= 0, "pow")
        return x ** int(y)
    _check_domain(x > 0 or (x == 0 and y > 0), "pow")
    return x**y


def sin_cos(angle: float) -> tuple[float, float]:
    """(sin, cos) of an angle [rad], each correctly rounded."""
    return sin(angle), cos(angle)


def sqrt(x: float) -> float:
    """The square root, which IEEE 754 already rounds correctly on every machine."""
    return math.sqrt(x)  # IEEE 754: correctly rounded everywhere


def parallel_axis(inertia, mass: float, d) -> np.ndarray:
    """I + m (|d|^2 1 - d d^T): an inertia about the centre of mass moved to a point at -d
    from it (Steiner), each entry exact and rounded once."""
    I = np.asarray(inertia, dtype=float)
    m = Fraction(float(mass))
    d = [Fraction(float(x)) for x in d]
    dd = sum((x * x for x in d), Fraction(0))
    return np.array(
        [
            [float(Fraction(float(I[i, j])) + m * ((dd if i == j else 0) - d[i] * d[j])) for j in range(3)]
            for i in range(3)
        ]
    )
