"""sin and cos of a kernel's angles, two angles at a time, in double precision.

A robot kernel's trigonometry is one sin and one cos per revolute joint, of the joint angle
(plus a constant offset), and those pairs were half the time of a small kernel through libm.
The emitted double code computes them with ``rg_sincos2``, a routine printed into the
source once: both angles' Cody-Waite reduction to r in [-pi/4, pi/4] (n = round(2x/pi),
r = x - n pi/2 with pi/2 in three parts), minimax polynomials of sin r (degree 13) and
cos r (degree 14) evaluated by Estrin's scheme, and the quadrant n mod 4 choosing and signing
them without a branch. The two angles' statements are written lane by lane, so that a
compiler may run both in one vector register (gcc and clang at -O2 on x86-64 do).

Bound: absolute error at most 2.3e-16 (about one unit in the last place of a number near 1)
for |x| <= 1e5; larger, infinite and NaN angles go to libm's sin and cos. The pi/2 split
comes from exact rational arithmetic and the polynomials' coefficients from decimal strings,
so the printed literals are the same on every machine. Float kernels keep sinf and cosf.

``pair_angles`` rewrites a straight-line program so that every angle (the value under a sin
or a cos) is computed first, then one SINCOS step computes all their sines and cosines,
and each sin or cos becomes a read of its lane.
"""

from __future__ import annotations

import math
from fractions import Fraction

import casadi as ca

from robotgen.emit import lane_names
from robotgen.emit.sx_program import Instruction, Program, defining_steps

HELPER = "rg_sincos2"
ANGLES, SINES, COSINES = "rg_x", "rg_s", "rg_c"  # a kernel's local arrays

# pseudo-operations of a paired program (CasADi's op codes are non-negative)
SINCOS = -1001  # args: the angles' registers, in lane order
SIN_LANE = -1002  # target = sin of lane ``element``
COS_LANE = -1003

ABOVE = 1.0e5  # |x| past this (or not finite) goes to libm

# pi to 80 digits, split as pi/2 = P1 + P2 + P3: P1 and P2 of 33 significant bits, so that
# n P1 and n P2 are exact for |n| < 2^20 (|x| <= 1e5 gives |n| <= 63662).
_PI = Fraction("3.1415926535897932384626433832795028841971693993751058209749445923078164062862")


def _leading_bits(value: Fraction, bits: int) -> Fraction:
    exponent = math.floor(math.log2(value))
    scale = Fraction(2) ** (bits - 1 - exponent)
    return Fraction(math.floor(value * scale)) / scale


_P1 = _leading_bits(_PI / 2, 33)
_P2 = _leading_bits(_PI / 2 - _P1, 33)
_P3 = _PI / 2 - _P1 - _P2
_TWO_OVER_PI = 2 / _PI
# The minimax polynomials of fdlibm's __kernel_sin and __kernel_cos (Sun Microsystems, 1993):
# sin r = r + r z (S1 + S2 z + ... + S6 z^5) and cos r = 1 + z (-1/2 + C1 z + ... + C6 z^6),
# z = r^2, |r| <= pi/4, each within 2^-57 of the function; degree 13 and 14 where the Taylor
# series needs 17 and 16. Printed from these decimal strings, the same literals everywhere.
SIN_TERMS = (
    "-1.66666666666666324348e-01",
    "8.33333333332248946124e-03",
    "-1.98412698298579493134e-04",
    "2.75573137070700676789e-06",
    "-2.50507602534068634195e-08",
    "1.58969099521155010221e-10",
)
COS_TERMS = (
    "-0.5",
    "4.16666666666666019037e-02",
    "-1.38888888888741095749e-03",
    "2.48015872894767294178e-05",
    "-2.75573143513906633035e-07",
    "2.08757232129817482790e-09",
    "-1.13596475577881948265e-11",
)


def _c(value: Fraction | str) -> str:
    """The nearest double as a C literal that reads back exactly."""
    return repr(float(value))


def _estrin(terms: tuple[str, ...], constant=lambda text: text) -> str:
    """c0 + c1 z + ... in lane l, with z2 = z^2 and z4 = z^4 (Estrin's scheme, 6 or 7 terms);
    ``constant`` spells each coefficient (a broadcast in the lane form)."""
    assert len(terms) in (6, 7), terms
    c = [constant(_c(t)) for t in terms]
    low = f"({c[0]} + z[l] * {c[1]}) + z2[l] * ({c[2]} + z[l] * {c[3]})"
    high = f"({c[4]} + z[l] * {c[5]})" + (f" + z2[l] * {c[6]}" if len(c) == 7 else "")
    return f"({low}) + z4[l] * ({high})"


def helper_source() -> str:
    """The C definition of ``rg_sincos2`` (static: each source that uses it has its own)."""
    return (
        "\n".join(
            [
                "/* sin and cos of x[0] and x[1] into s and c: reduction by pi/2 in three parts, minimax",
                " * polynomials on [-pi/4, pi/4], quadrant by arithmetic. Absolute error <= 2.3e-16 for",
                f" * |x| <= {ABOVE:g}; other angles (larger, infinite, NaN) through libm. Written lane by lane",
                " * so that the compiler may compute both lanes at once. */",
                f"static void {HELPER}(const double *x, double *s, double *c) {{",
                "  double y[2], k[2], r[2], z[2], z2[2], z4[2], ps[2], pc[2], sr[2], cr[2], w[2], ss[2], sc[2], "
                "so[2], co[2];",
                "  int n[2], l;",
                f"  if (!(fabs(x[0]) <= {ABOVE!r}) || !(fabs(x[1]) <= {ABOVE!r})) {{",
                "    for (l = 0; l < 2; ++l) {",
                "      s[l] = sin(x[l]);",
                "      c[l] = cos(x[l]);",
                "    }",
                "    return;",
                "  }",
                "  /* n = round(2 x / pi) (x + 65536.5 > 0, so the conversion truncates to the floor) */",
                f"  for (l = 0; l < 2; ++l) y[l] = x[l] * {_c(_TWO_OVER_PI)} + 65536.5;",
                "  for (l = 0; l < 2; ++l) n[l] = (int)y[l];",
                "  for (l = 0; l < 2; ++l) k[l] = (double)n[l] - 65536.0;",
                f"  for (l = 0; l < 2; ++l) r[l] = ((x[l] - k[l] * {_c(_P1)}) - k[l] * {_c(_P2)}) - k[l] * {_c(_P3)};",
                "  for (l = 0; l < 2; ++l) {",
                "    z[l] = r[l] * r[l];",
                "    z2[l] = z[l] * z[l];",
                "    z4[l] = z2[l] * z2[l];",
                "  }",
                f"  for (l = 0; l < 2; ++l) ps[l] = {_estrin(SIN_TERMS)};",
                f"  for (l = 0; l < 2; ++l) pc[l] = {_estrin(COS_TERMS)};",
                "  for (l = 0; l < 2; ++l) {",
                "    sr[l] = r[l] + (r[l] * z[l]) * ps[l];",
                "    cr[l] = 1.0 + z[l] * pc[l];",
                "  }",
                "  /* quadrant n mod 4: odd swaps sin and cos (w = 1); the signs of sin and cos */",
                "  for (l = 0; l < 2; ++l) {",
                "    w[l] = (double)(n[l] & 1);",
                "    ss[l] = (double)(1 - (n[l] & 2));",
                "    sc[l] = (double)(1 - ((n[l] + 1) & 2));",
                "  }",
                "  for (l = 0; l < 2; ++l) {",
                "    so[l] = ss[l] * (sr[l] * (1.0 - w[l]) + cr[l] * w[l]);",
                "    co[l] = sc[l] * (cr[l] * (1.0 - w[l]) + sr[l] * w[l]);",
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


def lane_helper_source() -> str:
    """``rg_sincos2`` for W states at once (robotgen.emit.lanes), printed once and compiled per
    width as RG_L(rg_sincos2): x, s and c hold two angles, each a vector of W states. Each lane
    takes rg_sincos2's operations in its order, so its bits: the same reduction and polynomials
    on vectors (RG_L(rg_sincos1), one angle), the quadrant from a vector of ints, and a lane
    whose pair has an angle past the bound (or not finite) through libm, both angles, as
    rg_sincos2 takes that pair. The polynomials see 0 in such a lane, so that no conversion to
    int overflows. |x| <= bound is written x <= bound and x >= -bound (the same lanes, NaN in
    neither), so that the test stays on vectors."""
    v, vi, mask = lane_names.VECTOR, lane_names.INT_VECTOR, lane_names.MASK_VECTOR

    def k(text: str) -> str:
        return lane_names.splat(text)

    def i(text: str) -> str:
        return f"{lane_names.INT_SPLAT}({text})"

    def within(x: str) -> str:
        return f"({x} <= {k(repr(ABOVE))}) & ({x} >= {k(repr(-ABOVE))})"

    one = lane_names.per_width("rg_sincos1")
    return (
        "\n".join(
            [
                "/* rg_sincos2's reduction, polynomials and quadrant on every lane of one angle x, "
                "|x| <= the bound. */",
                f"static {lane_names.TARGET} void {one}(const {v} *x, {v} *s, {v} *c) {{",
                f"  {v} y, k, r, z, z2, z4, ps, pc, sr, cr, w, ss, sc;",
                f"  {vi} n;",
                f"  y = *x * {k(_c(_TWO_OVER_PI))} + {k('65536.5')};",
                f"  n = __builtin_convertvector(y, {vi});",
                f"  k = __builtin_convertvector(n, {v}) - {k('65536.0')};",
                f"  r = ((*x - k * {k(_c(_P1))}) - k * {k(_c(_P2))}) - k * {k(_c(_P3))};",
                "  z = r * r;",
                "  z2 = z * z;",
                "  z4 = z2 * z2;",
                f"  ps = {_estrin(SIN_TERMS, k).replace('[l]', '')};",
                f"  pc = {_estrin(COS_TERMS, k).replace('[l]', '')};",
                "  sr = r + (r * z) * ps;",
                f"  cr = {k('1.0')} + z * pc;",
                f"  w = __builtin_convertvector(n & {i('1')}, {v});",
                f"  ss = __builtin_convertvector({i('1')} - (n & {i('2')}), {v});",
                f"  sc = __builtin_convertvector({i('1')} - ((n + {i('1')}) & {i('2')}), {v});",
                f"  *s = ss * (sr * ({k('1.0')} - w) + cr * w);",
                f"  *c = sc * (cr * ({k('1.0')} - w) + sr * w);",
                "}",
                "",
                "/* rg_sincos2 on every lane: two angles of W states, each lane computed as rg_sincos2 computes it. */",
                f"static {lane_names.TARGET} void {lane_names.per_width(HELPER)}(const {v} *x, {v} *s, {v} *c) {{",
                f"  {mask} near = {within('x[0]')} & {within('x[1]')};",
                f"  {v} a0 = ({v})(({mask})x[0] & near), a1 = ({v})(({mask})x[1] & near);",
                "  int m;",
                f"  {one}(&a0, s, c);",
                f"  {one}(&a1, s + 1, c + 1);",
                f"  for (m = 0; m < {lane_names.WIDTH}; ++m) {{",
                "    if (!near[m]) {",
                "      s[0][m] = sin(x[0][m]);",
                "      c[0][m] = cos(x[0][m]);",
                "      s[1][m] = sin(x[1][m]);",
                "      c[1][m] = cos(x[1][m]);",
                "    }",
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
