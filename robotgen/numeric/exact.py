"""Build-time arithmetic on the constants that robotgen prints into C, reproducible to the bit.

numpy's matrix products go to whichever BLAS kernel the CPU selects (fused multiply-adds or
not, other summation orders), and libm and numpy pick sin/cos/atan2 variants by CPU feature,
so the last bits of a DH placement or a merged inertia could differ between two machines
and show in the emitted C. Every constant of the model is therefore computed here instead:

- products and sums of matrices: each entry is the exact dot product (rational arithmetic on
  the doubles) rounded once to the nearest double;
- sin, cos, tan, atan2, exp, log and the other functions a spec's constant expressions may
  use: evaluated in 40-digit decimal arithmetic and rounded once to the nearest double;
- sqrt: IEEE 754 rounds it correctly on every machine.

So each result is the correctly rounded value of its exact definition, the same on every
machine and with every numpy, and no BLAS or libm call can change it.
"""
from __future__ import annotations

import math
from decimal import Decimal, localcontext
from fractions import Fraction

import numpy as np

_DIGITS = 40
# pi to 60 digits, for argument reduction of sin and cos
_PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494")


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
    return math.sqrt(dot(v, v))


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = norm(v)
    return np.array([float(Fraction(float(x)) / Fraction(n)) for x in v])


def cross(a, b) -> np.ndarray:
    return np.array([dot((a[1], -a[2]), (b[2], b[1])), dot((a[2], -a[0]), (b[0], b[2])),
                     dot((a[0], -a[1]), (b[1], b[0]))])


def outer(a, b) -> np.ndarray:
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


def _sin_cos_dec(x: Decimal) -> tuple[Decimal, Decimal]:
    """sin and cos of x by argument reduction to [-pi/4, pi/4] and Taylor series."""
    half_pi = _PI / 2
    k = int((x / half_pi).to_integral_value())
    r = x - k * half_pi
    r2 = r * r
    s, term, n = r, r, 1
    while True:
        term = -term * r2 / ((n + 1) * (n + 2))
        n += 2
        if term == 0 or abs(term) < Decimal(10) ** (-2 * _DIGITS):
            break
        s += term
    c, term, n = Decimal(1), Decimal(1), 0
    while True:
        term = -term * r2 / ((n + 1) * (n + 2))
        n += 2
        if term == 0 or abs(term) < Decimal(10) ** (-2 * _DIGITS):
            break
        c += term
    return [(s, c), (c, -s), (-s, -c), (-c, s)][k % 4]


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
    return s * (2 ** halvings)


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


def _rounded(compute):
    def f(*args: float) -> float:
        with localcontext() as ctx:
            ctx.prec = _DIGITS
            return float(compute(*(_dec(a) for a in args)))
    f.__name__ = compute.__name__
    return f


def _check_domain(ok: bool, name: str) -> None:
    if not ok:
        raise ValueError(f"math domain error in {name}")


@_rounded
def sin(x: Decimal) -> Decimal:
    return _sin_cos_dec(x)[0]


@_rounded
def cos(x: Decimal) -> Decimal:
    return _sin_cos_dec(x)[1]


@_rounded
def tan(x: Decimal) -> Decimal:
    s, c = _sin_cos_dec(x)
    return s / c


@_rounded
def atan(x: Decimal) -> Decimal:
    return _atan_dec(x)


@_rounded
def atan2(y: Decimal, x: Decimal) -> Decimal:
    return _atan2_dec(y, x)


@_rounded
def asin(x: Decimal) -> Decimal:
    _check_domain(abs(x) <= 1, "asin")
    return _atan2_dec(x, (1 - x * x).sqrt())


@_rounded
def acos(x: Decimal) -> Decimal:
    _check_domain(abs(x) <= 1, "acos")
    return _atan2_dec((1 - x * x).sqrt(), x)


@_rounded
def exp(x: Decimal) -> Decimal:
    return x.exp()


@_rounded
def log(x: Decimal) -> Decimal:
    _check_domain(x > 0, "log")
    return x.ln()


@_rounded
def sinh(x: Decimal) -> Decimal:
    return (x.exp() - (-x).exp()) / 2


@_rounded
def cosh(x: Decimal) -> Decimal:
    return (x.exp() + (-x).exp()) / 2


@_rounded
def tanh(x: Decimal) -> Decimal:
    a, b = x.exp(), (-x).exp()
    return (a - b) / (a + b)


@_rounded
def power(x: Decimal, y: Decimal) -> Decimal:
    if y == y.to_integral_value():
        _check_domain(x != 0 or y >= 0, "pow")
        return x ** int(y)
    _check_domain(x > 0 or (x == 0 and y > 0), "pow")
    return x ** y


def sin_cos(angle: float) -> tuple[float, float]:
    return sin(angle), cos(angle)


def sqrt(x: float) -> float:
    return math.sqrt(x)  # IEEE 754: correctly rounded everywhere


def parallel_axis(inertia, mass: float, d) -> np.ndarray:
    """I + m (|d|^2 1 - d d^T): an inertia about the centre of mass moved to a point at -d
    from it (Steiner), each entry exact and rounded once."""
    I = np.asarray(inertia, dtype=float)
    m = Fraction(float(mass))
    d = [Fraction(float(x)) for x in d]
    dd = sum((x * x for x in d), Fraction(0))
    return np.array([[float(Fraction(float(I[i, j])) + m * ((dd if i == j else 0) - d[i] * d[j]))
                      for j in range(3)] for i in range(3)])
