"""sin and cos of a kernel's angles, two angles at a time.

A robot kernel's trigonometry is one sin and one cos per revolute joint, of the joint angle
(plus a constant offset), and those pairs were half the time of a small kernel through libm.
The emitted code computes them with ``rg_sincos2``, a routine printed into the source once,
in the module's precision: both angles' Cody-Waite reduction to r in [-pi/4, pi/4]
(n = round(2x/pi), r = x - n pi/2 with pi/2 in three parts), minimax polynomials of sin r and
cos r evaluated by Estrin's scheme, and the quadrant n mod 4 choosing and signing them without
a branch. The two angles' statements are written lane by lane, so that a compiler may run both
in one vector register (gcc and clang at -O2 on x86-64 do).

Bounds (``ROUTINES``): in double, polynomials of degree 13 and 14, absolute error at most
2.3e-16 (about one unit in the last place of a number near 1) for |x| <= 1e5; in float,
degree 9 and 8, at most 1.0e-7 (1.7 units of 1.0's last place; libm's sinf is within one)
for |x| <= 4096. Larger, infinite and NaN angles go to libm. The pi/2 split comes from exact
rational arithmetic and the polynomials' coefficients from decimal strings, so the printed
literals are the same on every machine, and so are the sines and cosines, whatever the libm
(a Cortex-M's newlib or glibc).

``pair_angles`` rewrites a straight-line program so that every angle (the value under a sin
or a cos) is computed first, then one SINCOS step computes all their sines and cosines,
and each sin or cos becomes a read of its lane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import casadi as ca
import numpy as np

from robotgen.emit import lane_names
from robotgen.emit.sx_program import Instruction, Program, defining_steps

HELPER = "rg_sincos2"
LANE_HELPER = "rg_sincosn"  # a lane kernel's one call for all its angles (lane_helper_source)
ANGLES, SINES, COSINES = "rg_x", "rg_s", "rg_c"  # a kernel's local arrays

# pseudo-operations of a paired program (CasADi's op codes are non-negative)
SINCOS = -1001  # args: the angles' registers, in lane order
SIN_LANE = -1002  # target = sin of lane ``element``
COS_LANE = -1003

_PI = Fraction("3.1415926535897932384626433832795028841971693993751058209749445923078164062862")


def _leading_bits(value: Fraction, bits: int) -> Fraction:
    exponent = math.floor(math.log2(value))
    scale = Fraction(2) ** (bits - 1 - exponent)
    return Fraction(math.floor(value * scale)) / scale


@dataclass(frozen=True)
class Routine:
    """rg_sincos2 in one precision.

    above:  |x| past this (or not finite) goes to libm.
    offset: n + offset > 0 for every |x| <= above, so that the conversion to int truncates
            2x/pi + offset to round(2x/pi) + offset - 1/2.
    bits:   significant bits of the first two parts of pi/2, P1 and P2, so that n P1 and n P2
            are exact for every n of |x| <= above.
    sin_terms, cos_terms: sin r = r + r z (s_0 + s_1 z + ...), cos r = 1 + z (c_0 + c_1 z + ...),
            z = r^2, minimax on |r| <= pi/4."""

    real: str
    above: float
    offset: float
    bits: int
    sin_terms: tuple[str, ...]
    cos_terms: tuple[str, ...]

    @property
    def suffix(self) -> str:
        """Of C's float literals and math functions: "f" in float."""
        return "f" if self.real == "float" else ""

    def literal(self, value: Fraction | str | float) -> str:
        """The nearest value of the type as a C literal that reads back exactly."""
        if self.real == "double":
            return repr(float(value))
        v = float(np.float32(float(value)))
        text = next(t for t in (f"{v:.{d}g}" for d in range(1, 10)) if float(np.float32(float(t))) == v)
        return text + ("" if any(c in text for c in ".e") else ".0") + "f"

    @property
    def parts(self) -> tuple[Fraction, Fraction, Fraction]:
        """pi/2 = P1 + P2 + P3."""
        p1 = _leading_bits(_PI / 2, self.bits)
        p2 = _leading_bits(_PI / 2 - p1, self.bits)
        return p1, p2, _PI / 2 - p1 - p2

    def polynomial(self, terms: tuple[str, ...], constant=None) -> str:
        """c0 + c1 z + ... in lane l by Estrin's scheme (z2 = z^2, z4 = z^4); ``constant``
        spells each coefficient (a broadcast in the lane form)."""
        c = [(constant or (lambda text: text))(self.literal(t)) for t in terms]
        low = f"({c[0]} + z[l] * {c[1]}) + z2[l] * ({c[2]} + z[l] * {c[3]})"
        if len(c) == 4:
            return low
        assert len(c) in (6, 7), terms
        high = f"({c[4]} + z[l] * {c[5]})" + (f" + z2[l] * {c[6]}" if len(c) == 7 else "")
        return f"({low}) + z4[l] * ({high})"

    @property
    def needs_z4(self) -> bool:
        """Whether the polynomials read z^4 (more than four terms)."""
        return max(len(self.sin_terms), len(self.cos_terms)) > 4


ROUTINES = {
    # pi/2 in parts of 33 bits: |x| <= 1e5 gives |n| <= 63662 < 2^20. The polynomials are fdlibm's
    # __kernel_sin and __kernel_cos (Sun Microsystems, 1993), each within 2^-57 of the function on
    # |r| <= pi/4: degree 13 and 14, where the Taylor series needs 17 and 16.
    "double": Routine(
        "double",
        above=1.0e5,
        offset=65536.5,
        bits=33,
        sin_terms=(
            "-1.66666666666666324348e-01",
            "8.33333333332248946124e-03",
            "-1.98412698298579493134e-04",
            "2.75573137070700676789e-06",
            "-2.50507602534068634195e-08",
            "1.58969099521155010221e-10",
        ),
        cos_terms=(
            "-0.5",
            "4.16666666666666019037e-02",
            "-1.38888888888741095749e-03",
            "2.48015872894767294178e-05",
            "-2.75573143513906633035e-07",
            "2.08757232129817482790e-09",
            "-1.13596475577881948265e-11",
        ),
    ),
    # pi/2 in parts of 12 bits: |x| <= 4096 gives |n| <= 2608 < 2^12. Polynomials fitted for robotgen
    # (Lawson's iteration to the minimax on |r| <= 1.003 pi/4, c_0 of cos held at -1/2), then rounded
    # to float: within 2^-27 of each function, below float's own rounding (2^-24 near 1).
    "float": Routine(
        "float",
        above=4096.0,
        offset=4096.5,
        bits=12,
        sin_terms=("-0.16666667", "0.008333329", "-0.00019839288", "2.7178965e-06"),
        cos_terms=("-0.5", "0.041666646", "-0.0013887349", "2.4436291e-05"),
    ),
}
ABOVE = ROUTINES["double"].above  # the double routine's bound (what tests and docs quote)


def helper_source(real: str = "double") -> str:
    """The C definition of ``rg_sincos2`` in C type ``real`` (static: each source that uses it has its own)."""
    t = ROUTINES[real]
    f, k = t.suffix, t.literal
    p1, p2, p3 = t.parts
    temporaries = (
        "y, k, r, z, z2, z4, ps, pc, sr, cr, w, ss, sc, so, co"
        if t.needs_z4
        else ("y, k, r, z, z2, ps, pc, sr, cr, w, ss, sc, so, co")
    )
    bound = "2.3e-16" if real == "double" else "1.0e-7"
    return (
        "\n".join(
            [
                "/* sin and cos of x[0] and x[1] into s and c: reduction by pi/2 in three parts, minimax",
                f" * polynomials on [-pi/4, pi/4], quadrant by arithmetic. Absolute error <= {bound} for",
                f" * |x| <= {t.above:g}; other angles (larger, infinite, NaN) through libm. Written lane by lane",
                " * so that the compiler may compute both lanes at once. */",
                f"static void {HELPER}(const {real} *x, {real} *s, {real} *c) {{",
                f"  {real} " + ", ".join(f"{v}[2]" for v in temporaries.split(", ")) + ";",
                "  int n[2], l;",
                f"  if (!(fabs{f}(x[0]) <= {k(t.above)}) || !(fabs{f}(x[1]) <= {k(t.above)})) {{",
                "    for (l = 0; l < 2; ++l) {",
                f"      s[l] = sin{f}(x[l]);",
                f"      c[l] = cos{f}(x[l]);",
                "    }",
                "    return;",
                "  }",
                f"  /* n = round(2 x / pi) (x + {t.offset:g} > 0, so the conversion truncates to the floor) */",
                f"  for (l = 0; l < 2; ++l) y[l] = x[l] * {k(2 / _PI)} + {k(t.offset)};",
                "  for (l = 0; l < 2; ++l) n[l] = (int)y[l];",
                f"  for (l = 0; l < 2; ++l) k[l] = ({real})n[l] - {k(t.offset - 0.5)};",
                f"  for (l = 0; l < 2; ++l) r[l] = ((x[l] - k[l] * {k(p1)}) - k[l] * {k(p2)}) - k[l] * {k(p3)};",
                "  for (l = 0; l < 2; ++l) {",
                "    z[l] = r[l] * r[l];",
                "    z2[l] = z[l] * z[l];",
                *(["    z4[l] = z2[l] * z2[l];"] if t.needs_z4 else []),
                "  }",
                f"  for (l = 0; l < 2; ++l) ps[l] = {t.polynomial(t.sin_terms)};",
                f"  for (l = 0; l < 2; ++l) pc[l] = {t.polynomial(t.cos_terms)};",
                "  for (l = 0; l < 2; ++l) {",
                "    sr[l] = r[l] + (r[l] * z[l]) * ps[l];",
                f"    cr[l] = {k(1.0)} + z[l] * pc[l];",
                "  }",
                "  /* quadrant n mod 4: odd swaps sin and cos (w = 1); the signs of sin and cos */",
                "  for (l = 0; l < 2; ++l) {",
                f"    w[l] = ({real})(n[l] & 1);",
                f"    ss[l] = ({real})(1 - (n[l] & 2));",
                f"    sc[l] = ({real})(1 - ((n[l] + 1) & 2));",
                "  }",
                "  for (l = 0; l < 2; ++l) {",
                f"    so[l] = ss[l] * (sr[l] * ({k(1.0)} - w[l]) + cr[l] * w[l]);",
                f"    co[l] = sc[l] * (cr[l] * ({k(1.0)} - w[l]) + sr[l] * w[l]);",
                "  }",
                "  /* stored lane by lane: s and c may overlap, so a loop writing them would stay scalar */",
                "  s[0] = so[0];",
                "  s[1] = so[1];",
                "  c[0] = co[0];",
                "  c[1] = co[1];",
                "}",
            ]
        )
        + "\n"
    )


def lane_helper_source(real: str = "double") -> str:
    """``rg_sincos2`` for W states at once (robotgen.emit.lanes), printed once and compiled per
    width as RG_L(rg_sincos2): x, s and c hold two angles, each a vector of W states; and
    RG_L(rg_sincosn), a lane kernel's one call for its n angles: when every lane is within the
    bound, rg_sincos1 on each angle with no test per pair (a lane kernel's angles are all
    within on nearly every call), else RG_L(rg_sincos2) pair by pair. Each lane
    takes rg_sincos2's operations in its order, so its bits: the same reduction and polynomials
    on vectors (RG_L(rg_sincos1), one angle), and a lane whose pair has an angle past the bound
    (or not finite) through libm, both angles, as rg_sincos2 takes that pair. rg_sincos2's
    (int)y and the quadrant's arithmetic have exact vector forms without a conversion between
    ints and reals (GCC 12 splits an 8-lane one in four): the floor by adding 2^52 (2^23), and
    the choice and signs by masks on the bits. The polynomials see 0 in a lane past the bound.
    |x| <= bound is written x <= bound and x >= -bound (the same lanes, NaN in neither), so
    that the test stays on vectors."""
    t = ROUTINES[real]
    f = t.suffix
    p1, p2, p3 = t.parts
    v, mask = lane_names.VECTOR, lane_names.MASK_VECTOR
    magic = 52 if real == "double" else 23  # the type's fraction bits: past 2^magic, reals are integers

    def k(value) -> str:
        return lane_names.splat(t.literal(value))

    def within(x: str) -> str:
        return f"({x} <= {k(t.above)}) & ({x} >= {k(-t.above)})"

    one = lane_names.per_width("rg_sincos1")
    pair, many = lane_names.per_width(HELPER), lane_names.per_width(LANE_HELPER)
    return (
        "\n".join(
            [
                "/* rg_sincos2's reduction, polynomials and quadrant on every lane of one angle x, "
                "|x| <= the bound. */",
                f"static {lane_names.TARGET} void {one}(const {v} *x, {v} *s, {v} *c) {{",
                f"  {v} y, t, f, k, r, z, z2, {'z4, ' if t.needs_z4 else ''}ps, pc, sr, cr;",
                f"  {mask} up, n, w, sign_s, sign_c;",
                f"  y = *x * {k(2 / _PI)} + {k(t.offset)};",
                f"  /* floor(y), rg_sincos2's (int)y, without a conversion: y + 2^{magic} is y rounded to an",
                "   * integer, one less where that is above y; n's low bits are the floor's */",
                f"  t = y + {k(2.0**magic)};",
                f"  f = t - {k(2.0**magic)};",
                "  up = f > y;",
                f"  n = ({mask})t + up;",
                f"  k = (f - ({v})(up & ({mask}){k(1.0)})) - {k(t.offset - 0.5)};",
                f"  r = ((*x - k * {k(p1)}) - k * {k(p2)}) - k * {k(p3)};",
                "  z = r * r;",
                "  z2 = z * z;",
                *(["  z4 = z2 * z2;"] if t.needs_z4 else []),
                f"  ps = {t.polynomial(t.sin_terms, lane_names.splat).replace('[l]', '')};",
                f"  pc = {t.polynomial(t.cos_terms, lane_names.splat).replace('[l]', '')};",
                "  sr = r + (r * z) * ps;",
                f"  cr = {k(1.0)} + z * pc;",
                "  /* quadrant n mod 4: odd (w all ones) swaps sin and cos; bit 1 negates sin, bit 1 of n + 1",
                "   * (bit 1 xor bit 0) cos. rg_sincos2's ss (sr (1 - w) + cr w) bit for bit: cr > 0, and sr",
                "   * is never -0 */",
                "  w = -(n & 1);",
                f"  sign_s = -((n >> 1) & 1) & ({mask}){k(-0.0)};",
                f"  sign_c = sign_s ^ (w & ({mask}){k(-0.0)});",
                f"  *s = ({v})(((({mask})sr & ~w) | (({mask})cr & w)) ^ sign_s);",
                f"  *c = ({v})(((({mask})cr & ~w) | (({mask})sr & w)) ^ sign_c);",
                "}",
                "",
                "/* rg_sincos2 on every lane: two angles of W states, each lane computed as rg_sincos2 computes it. */",
                f"static {lane_names.TARGET} void {pair}(const {v} *x, {v} *s, {v} *c) {{",
                f"  {mask} near = {within('x[0]')} & {within('x[1]')};",
                f"  {v} a0 = ({v})(({mask})x[0] & near), a1 = ({v})(({mask})x[1] & near);",
                "  int m;",
                f"  {one}(&a0, s, c);",
                f"  {one}(&a1, s + 1, c + 1);",
                f"  for (m = 0; m < {lane_names.WIDTH}; ++m) {{",
                "    if (!near[m]) {",
                f"      s[0][m] = sin{f}(x[0][m]);",
                f"      c[0][m] = cos{f}(x[0][m]);",
                f"      s[1][m] = sin{f}(x[1][m]);",
                f"      c[1][m] = cos{f}(x[1][m]);",
                "    }",
                "  }",
                "}",
                "",
                "/* sin and cos of a lane kernel's n angles, each lane as rg_sincos2 computes the kernel's pairs",
                " * (angles 2i and 2i + 1; the last, when n is odd, with 0). When every lane of every angle is",
                " * within the bound, the angles go through rg_sincos1 one after the other, with no pair's",
                " * test between them, else pair by pair through RG_L(rg_sincos2). */",
                f"static {lane_names.TARGET} void {many}(int n, const {v} *x, {v} *s, {v} *c) {{",
                f"  {mask} near = {within('x[0]')};",
                "  int j, m, far = 0;",
                f"  for (j = 1; j < n; ++j) near &= {within('x[j]')};",
                f"  for (m = 0; m < {lane_names.WIDTH}; ++m) far |= !near[m];",
                "  if (!far) {",
                f"    for (j = 0; j < n; ++j) {one}(x + j, s + j, c + j);",
                "    return;",
                "  }",
                f"  for (j = 0; j + 1 < n; j += 2) {pair}(x + j, s + j, c + j);",
                "  if (j < n) {",
                f"    {v} a[2], b[2], d[2];",
                "    a[0] = x[j];",
                f"    a[1] = {k(0.0)};",
                f"    {pair}(a, b, d);",
                "    s[j] = b[0];",
                "    c[j] = d[0];",
                "  }",
                "}",
            ]
        )
        + "\n"
    )


def uses_helper(program: Program) -> bool:
    """Whether the program calls rg_sincos2 (so the source must define it)."""
    return any(step.op == SINCOS for step in program.instructions)


def lanes(program: Program) -> int:
    """The length of the kernel's angle arrays (the angles rounded up to pairs)."""
    step = next(s for s in program.instructions if s.op == SINCOS)
    return len(step.args) + len(step.args) % 2


def pair_angles(program: Program) -> Program:
    """``program`` with its angles computed first and one SINCOS step for them all.

    An angle is the value a sin or cos reads, identified by the step that wrote it (registers
    are reused). The steps it depends on move to the front with fresh registers (in their
    order; they have no side effects), the SINCOS step follows, and the rest keeps its order,
    reading the moved values through their fresh registers. An angle that itself depends on a
    sin or cos keeps libm."""
    steps = program.instructions
    defs = defining_steps(steps)  # per step, the steps that wrote what it reads
    trig = (ca.OP_SIN, ca.OP_COS)

    def closure(k: int, seen: set[int]) -> bool:
        """Adds step k and what it reads to ``seen``; False if a sin or cos is among them."""
        stack = [k]
        while stack:
            j = stack.pop()
            if j in seen:
                continue
            if j < 0 or steps[j].op in trig:
                return False
            seen.add(j)
            stack.extend(defs[j])
        return True

    angles: list[int] = []  # the steps writing each angle, in lane order
    hoisted: set[int] = set()
    for k, step in enumerate(steps):
        if step.op in trig and defs[k][0] not in angles:
            seen = set(hoisted)
            if closure(defs[k][0], seen):
                angles.append(defs[k][0])
                hoisted = seen
    if not angles:
        return program
    fresh = max((s.target for s in steps), default=-1) + 1
    renamed = {j: fresh + i for i, j in enumerate(sorted(hoisted))}
    lane = {j: i for i, j in enumerate(angles)}

    def args(k: int) -> tuple[int, ...]:
        return tuple(renamed.get(d, r) for d, r in zip(defs[k], steps[k].args))

    front = [
        Instruction(steps[j].op, renamed[j], args(j), steps[j].port, steps[j].element, steps[j].constant)
        for j in sorted(hoisted)
    ]
    front.append(Instruction(SINCOS, -1, tuple(renamed[j] for j in angles)))
    rest = []
    for k, step in enumerate(steps):
        if k in hoisted:
            continue
        if step.op in trig and defs[k][0] in lane:
            rest.append(
                Instruction(SIN_LANE if step.op == ca.OP_SIN else COS_LANE, step.target, element=lane[defs[k][0]])
            )
        else:
            rest.append(Instruction(step.op, step.target, args(k), step.port, step.element, step.constant))
    return Program((*front, *rest), program.unwritten_outputs)
