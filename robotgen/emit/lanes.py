"""Batches across states: SIMD lanes, one state per lane.

A function with a batch form gets ``<name>_<fn>_batch(int n, const real *q, ..., real *out)``
(and ``..._batch_lanes(int lanes, int n, ...)``, which caps the width). Its arguments are n
states laid out as callers hold them, one state after the other (array of structures: state k
of port q at ``q + k * <size of q>``). The batch driver takes them W at a time, transposes each
block into structure-of-arrays form (a vector per port element, state b + l in lane l), runs the
function's lane kernel (c_kernel.lane_kernel_source: the single-state function's statements, in
its order, on vectors; sin/cos of all its angles in one call, rg_sincosn) and transposes the results
back. The states left over (n mod W) go through the single-state function.

Each lane computes the IEEE operations the single-state function computes on that state, in the
same order and uncontracted (robotgen compiles with -ffp-contract=off; a user's build gets the
same guarantee under -std=c99 or that flag), so a batch is bit-identical to n single calls: the
tests compare every function with a batch form, at every width this CPU runs.

The widths (``WIDTHS``): AVX-512F, 8 doubles (16 floats), and AVX2, 4 (8), on x86-64, each copy
compiled with ``__attribute__((target(...)))`` and chosen at run time by
``__builtin_cpu_supports``; NEON, 2 (4), on aarch64; elsewhere (a Cortex-M, a compiler that is
not GCC or Clang) every state goes through the single-state function. The lane kernels are
rendered once and ``<name>.c`` holds a copy for each width, after that width's definitions
of the names of robotgen.emit.lane_names.
"""

from __future__ import annotations

from dataclasses import dataclass

from robotgen.emit import lane_names
from robotgen.emit.c_kernel import STEP_PORT, Precision, function_name, is_parameter_port, params_type
from robotgen.symbolic.kernel import Kernel

# The functions with a batch form: the dynamics a sampling MPC or a trajectory optimiser
# evaluates over many states, and their derivatives (a tree's plant for simulating many at once).
BATCH_FUNCTIONS = frozenset(
    {
        "mass",
        "gravity",
        "inverse_dynamics",
        "forward_dynamics",
        "mass_inverse",
        "inverse_dynamics_derivatives",
        "forward_dynamics_derivatives",
        "discrete_dynamics",
        "discrete_dynamics_derivatives",
        "plant_dynamics",
    }
)
# Lanes are compiled for robots of at most this many coordinates: past it, each state of a batch
# goes through the single-state function. A long chain's or a humanoid's kernels are loops
# (symbolic/chain_loops.py), and their lane copies tripled the build: the 30-joint chain of
# bench/scaling.py built in 9.5 s against 2.5, the 32-joint iCub in 11.9 s against 4.3.
LANES_MAX_NQ = 12
DRIVER = "rgb_"  # a function's batch driver: static, rgb_<kernel> per width
SELECT = "rg_batch_width"  # the static width chooser


@dataclass(frozen=True)
class Width:
    """One compiled copy of the lane kernels: ``guard`` says where (a macro the source defines
    from the compiler's), ``vector_bytes`` the vector's size, ``target`` the instruction set
    its functions are compiled for (empty: the baseline), ``cpu_feature`` what
    __builtin_cpu_supports must say at run time (empty: always there)."""

    name: str
    guard: str
    vector_bytes: int
    target: str
    cpu_feature: str

    def lanes(self, precision: Precision) -> int:
        """States per vector at this width in ``precision``'s reals."""
        return self.vector_bytes // (8 if precision.real == "double" else 4)


X86, NEON = "RG_LANES_X86", "RG_LANES_NEON"
# widest first: the order in which a batch call tries them
WIDTHS = (
    Width("avx512", X86, 64, "avx512f", "avx512f"),
    Width("avx2", X86, 32, "avx2", "avx2"),
    Width("neon", NEON, 16, "", ""),
)
# Where lanes are compiled at all: GCC or Clang with __builtin_convertvector (GCC 9), on x86-64
# or aarch64; -DRG_NO_LANES turns them off.
LANES_GUARD = (
    "#if defined(__GNUC__) && (defined(__clang__) || __GNUC__ >= 9) && !defined(RG_NO_LANES)\n"
    "#if defined(__x86_64__)\n"
    f"#define {X86} 1\n"
    "#elif defined(__aarch64__)\n"
    f"#define {NEON} 1\n"
    "#endif\n"
    "#endif\n"
    f"#if defined(__clang__) && (defined({X86}) || defined({NEON}))\n"
    "#pragma STDC FP_CONTRACT OFF\n"
    "#endif\n"
)


def has_batch(kernel: Kernel) -> bool:
    """The kernel has a _batch entry point."""
    return kernel.name in BATCH_FUNCTIONS


def batch_name(prefix: str, kernel: Kernel) -> str:
    """The C name of the kernel's _batch entry point."""
    return function_name(prefix, kernel) + "_batch"


def input_sizes(kernels) -> tuple[int, ...]:
    """The sizes of the batch functions' input ports (their gathers)."""
    return tuple(sorted({p.size for k in kernels if has_batch(k) for p in _array_ports(k)}))


def _array_ports(kernel: Kernel):
    return [p for p in kernel.inputs if not is_parameter_port(p)]


def batch_prototypes(prefix: str, kernel: Kernel, precision: Precision) -> tuple[str, str]:
    """(``<fn>_batch``, ``<fn>_batch_lanes``) prototypes, without the semicolon."""
    params = [
        f"const {params_type(prefix)} *{p.name}" if is_parameter_port(p) else f"const {precision.real} *{p.name}"
        for p in kernel.inputs
    ]
    params += [f"{precision.real} *{p.name}" for p in kernel.outputs]
    name = batch_name(prefix, kernel)
    return (f"int {name}(int n, {', '.join(params)})", f"int {name}_lanes(int lanes, int n, {', '.join(params)})")


def width_open(width: Width, precision: Precision, sizes: tuple[int, ...] = ()) -> str:
    """The definitions of lane_names for ``width`` (before its copy of the lane kernels), and its
    gathers of the input ports' ``sizes`` that are deinterleaved (``deinterleaved``)."""
    w = width.lanes(precision)
    splat = ", ".join(["(x)"] * w)
    # never a multiply-add: GCC fuses across statements in GNU mode (AVX-512F has FMA), Clang within
    # an expression (the sin/cos polynomials); Clang's is turned off by the pragma of LANES_GUARD
    isa = f'target("{width.target}")' if width.target else ""
    target = f"__attribute__(({isa}))" if isa else ""
    gcc_target = f'__attribute__(({isa + ", " if isa else ""}optimize("fp-contract=off")))'
    vector = f"rg_v_{width.name}"
    return (
        "\n".join(
            [
                f"#if defined({width.guard})",
                f"typedef {precision.real} {vector} __attribute__((vector_size({width.vector_bytes})));",
                f"#define {lane_names.VECTOR} {vector}",
                # what a comparison gives: a type of its own in Clang; in GCC an opaque type that
                # converts to this one (which its shuffles take as their mask)
                "#if defined(__clang__)",
                f"typedef __typeof__(({vector}){{0}} < ({vector}){{0}}) rg_vm_{width.name};",
                "#else",
                f"typedef {'long long' if precision.real == 'double' else 'int'} rg_vm_{width.name} "
                f"__attribute__((vector_size({width.vector_bytes})));",
                "#endif",
                f"#define {lane_names.MASK_VECTOR} rg_vm_{width.name}",
                f"#define {lane_names.WIDTH} {w}",
                f"#define {lane_names.SPLAT}(x) (({lane_names.VECTOR}){{{splat}}})",
                "#if defined(__clang__)",
                f"#define {lane_names.TARGET} {target}".rstrip(),
                "#else",
                f"#define {lane_names.TARGET} {gcc_target}",
                "#endif",
                f"#define {lane_names.PER_WIDTH}(name) name##_{width.name}",
                *_transposes(w, precision),
                *(line for size in sizes if deinterleaved(size, w) for line in _deinterleave(w, precision, size)),
            ]
        )
        + "\n"
    )


def _transpose_steps(w: int) -> list[tuple[int, int, list[int], list[int]]]:
    """A W x W transpose of rows t[0..W-1] in log2(W) steps: at step b (1, 2, 4, ...), rows i and
    i + b (i without the bit b) swap their off-diagonal b x b blocks. (i, j, lanes of new t[i],
    lanes of new t[j]), in a shuffle's numbering (t[i]'s lanes 0..W-1, t[j]'s W..2W-1)."""
    steps, b = [], 1
    while b < w:
        for i in (i for i in range(w) if not i & b):
            steps.append(
                (
                    i,
                    i + b,
                    [w + lane - b if lane & b else lane for lane in range(w)],
                    [w + lane if lane & b else lane + b for lane in range(w)],
                )
            )
        b *= 2
    return steps


def _shuffle_macro() -> list[str]:
    """RG_SHUFFLE(a, b, lanes...): a shuffle of two vectors by constant lanes (a's 0..W-1, b's
    W..2W-1), GCC's __builtin_shuffle or Clang's __builtin_shufflevector; #undef after use."""
    return [
        "#if defined(__clang__)",
        "#define RG_SHUFFLE(a, b, ...) __builtin_shufflevector(a, b, __VA_ARGS__)",
        "#else",
        f"#define RG_SHUFFLE(a, b, ...) __builtin_shuffle(a, b, ({lane_names.MASK_VECTOR}){{__VA_ARGS__}})",
        "#endif",
    ]


def _step(step: tuple[int, int, list[int], list[int]], rows: str, indent: str = "  ") -> list[str]:
    """One step of _transpose_steps on the vectors ``rows``[i] and ``rows``[j], through a and b."""
    i, j, low, high = step
    return [
        f"{indent}a = RG_SHUFFLE({rows}[{i}], {rows}[{j}], {', '.join(map(str, low))});",
        f"{indent}b = RG_SHUFFLE({rows}[{i}], {rows}[{j}], {', '.join(map(str, high))});",
        f"{indent}{rows}[{i}] = a;",
        f"{indent}{rows}[{j}] = b;",
    ]


def _transposes(w: int, precision: Precision) -> list[str]:
    """RG_L(rg_gather) and RG_L(rg_scatter): W consecutive elements of W states (stride apart)
    to and from W vectors (element e of every state in t[e]), through a transpose in registers
    (log2 W steps of shuffles; they commute). A scatter's last step (rows i and i + W/2 swapping
    their W/2 x W/2 blocks) is done by its stores: each half vector stored where it belongs, so
    that it costs no shuffle. Shuffles of GCC (__builtin_shuffle) or Clang
    (__builtin_shufflevector)."""
    v, real = lane_names.VECTOR, precision.real
    size = 8 if real == "double" else 4
    half = w // 2
    steps = [step for step in _transpose_steps(w) if step[1] - step[0] < half]
    transpose = lane_names.per_width("rg_transpose")
    top = [step for step in _transpose_steps(w) if step[1] - step[0] == half]
    lines = _shuffle_macro()
    if steps:
        lines += [f"static inline {lane_names.TARGET} void {transpose}({v} *t) {{", f"  {v} a, b;"]
        for step in steps:
            lines += _step(step, "t")
        lines.append("}")
    call = [f"  {transpose}(r);"] if steps else []
    # W and W/2 elements at any address of the real type: under-aligned vectors that may alias it
    whole, unaligned = lane_names.per_width("rg_vu"), lane_names.per_width("rg_vh")

    def part(row: int, first: int) -> str:  # W/2 lanes of r[row] from lane ``first``
        return f"((const {unaligned} *)&r[{row}])[{first // half}]"

    lines += [
        f"typedef {real} {whole} __attribute__((vector_size({w * size}), aligned({size}), may_alias));",
        f"typedef {real} {unaligned} __attribute__((vector_size({half * size}), aligned({size}), may_alias));",
        f"static {lane_names.TARGET} __attribute__((unused)) void {lane_names.per_width('rg_gather')}"
        f"({v} *t, const {real} *p, size_t stride) {{",
        f"  {v} r[{w}];",
        *(f"  r[{l}] = *(const {whole} *)(p + {l} * stride);" for l in range(w)),
        *call,
    ]
    for i, j, low, high in top:
        lines += [
            f"  t[{i}] = RG_SHUFFLE(r[{i}], r[{j}], {', '.join(map(str, low))});",
            f"  t[{j}] = RG_SHUFFLE(r[{i}], r[{j}], {', '.join(map(str, high))});",
        ]
    lines += ["}", "#undef RG_SHUFFLE"]
    lines += [
        f"static {lane_names.TARGET} __attribute__((unused)) void {lane_names.per_width('rg_scatter')}"
        f"({real} *p, size_t stride, const {v} *t) {{",
        f"  {v} r[{w}];",
        *(f"  r[{l}] = t[{l}];" for l in range(w)),
        *call,
    ]
    for l in range(half):
        for first in (0, half):
            lines += [
                f"  *({unaligned} *)(p + {l} * stride + {first}) = {part(l + first, 0)};",
                f"  *({unaligned} *)(p + {l + half} * stride + {first}) = {part(l + first, half)};",
            ]
    lines.append("}")
    return lines + _scatter_part(w, precision, steps) + _gather_part(w, precision, steps, top)


def _gather_part(w: int, precision: Precision, steps, top) -> list[str]:
    """RG_L(rg_gather_part)(t, p, stride, n): rg_gather of the first n < W of W elements (a
    port's last size mod W) into t[0..n-1]: each vector built from W/2 elements of state i and
    W/2 of state i + W/2 (the transpose's last step, done by the loads), the absent elements 0;
    then the other steps. Inlined where n is a constant, the tests fold away."""
    v, real = lane_names.VECTOR, precision.real
    half = w // 2
    zero = "0.0f" if real == "float" else "0.0"
    lines = [
        f"static inline {lane_names.TARGET} __attribute__((unused, always_inline)) void "
        f"{lane_names.per_width('rg_gather_part')}({v} *t, const {real} *p, size_t stride, int n) {{",
        f"  {v} r[{w}]{', a, b' if steps else ''};",
    ]
    for i, j, _, _ in top:
        for row, first in ((i, 0), (j, half)):
            lanes = [
                f"{first + k} < n ? p[{state} * stride + {first + k}] : {zero}" for state in (i, j) for k in range(half)
            ]
            lines.append(f"  r[{row}] = ({v}){{{', '.join(lanes)}}};")
    if steps:
        lines += _shuffle_macro()
        for step in steps:
            lines += _step(step, "r")
        lines.append("#undef RG_SHUFFLE")
    lines += [f"  if ({e} < n) t[{e}] = r[{e}];" for e in range(w - 1)]
    lines.append("}")
    return lines


def _scatter_part(w: int, precision: Precision, steps) -> list[str]:
    """RG_L(rg_scatter_part)(p, stride, t, n): rg_scatter of the first n < W of W elements (a
    port's last size mod W), the absent rows standing in as copies of t[0]. A step of the
    transpose is skipped where both its rows hold only absent elements (after the steps below
    bit b, row i holds those of rows i & ~(b - 1) and up); the rows' first n lanes are stored as
    pieces of W/2, W/4, ..., 1 elements. Inlined where n is a constant, the tests fold away."""
    v, real = lane_names.VECTOR, precision.real
    size = 8 if real == "double" else 4
    half = w // 2
    pieces = [k for k in (half >> s for s in range(half.bit_length())) if k]  # half, ..., 1
    lines = [
        *(
            f"typedef {real} {lane_names.per_width(f'rg_vp{k}')} __attribute__((vector_size({k * size}), "
            f"aligned({size}), may_alias));"
            for k in pieces
            if 1 < k < half  # W/2: rg_scatter's rg_vh
        ),
        f"static inline {lane_names.TARGET} __attribute__((unused, always_inline)) void "
        f"{lane_names.per_width('rg_scatter_part')}"
        f"({real} *p, size_t stride, const {v} *t, int n) {{",
        f"  {v} r[{w}]{', a, b' if steps else ''};",
        "  int o;",
        "  r[0] = t[0];",
        *(f"  r[{l}] = t[{l} < n ? {l} : 0];" for l in range(1, w)),
    ]
    if steps:
        lines += _shuffle_macro()
    for step in steps:
        i, j = step[0], step[1]
        lines += [f"  if ({i & ~(j - i - 1)} < n) {{", *_step(step, "r", "    "), "  }"]
    if steps:
        lines.append("#undef RG_SHUFFLE")

    def piece(k: int) -> str:
        return real if k == 1 else lane_names.per_width("rg_vh" if k == half else f"rg_vp{k}")

    def store(state: int, row: int, lane: int, element: int, k: int) -> str:
        # k lanes of r[row] from ``lane`` + o to state's elements from ``element`` + o
        return (
            f"*({piece(k)} *)(p + {state} * stride + {element} + o) = "
            f"((const {piece(k)} *)&r[{row}])[({lane} + o) / {k}];"
        )

    for first, count in ((0, "n"), (half, f"n - {half}")):
        lines.append(f"  if ({count} > 0) {{" if first else "  {")
        lines.append(f"    int m = {count} < {half} ? {count} : {half};")
        lines.append("    o = 0;")
        for k in pieces:
            lines.append(f"    if (m & {k}) {{")
            for l in range(half):
                lines.append("      " + store(l, l + first, 0, first, k))
                lines.append("      " + store(l + half, l + first, half, first, k))
            lines.append(f"      o += {k};")
            lines.append("    }")
        lines.append("  }")
    lines.append("}")
    return lines


def deinterleaved(size: int, w: int) -> bool:
    """Whether a port of ``size`` < W elements comes into W lanes by deinterleaving (W states'
    elements are ``size`` whole vectors; each element's vector takes lanes from up to ``size`` of
    them, size - 1 two-vector shuffles) rather than by a W x W transpose (W log2 W shuffles)."""
    return size < w and size * (size - 1) < w * (w.bit_length() - 1)


def _deinterleave(w: int, precision: Precision, size: int) -> list[str]:
    """RG_L(rg_deinterleave<size>)(t, p): W states of ``size`` elements from p (W * size reals
    one after the other) into t[0..size-1], element e of state l in lane l of t[e]."""
    v, real = lane_names.VECTOR, precision.real
    whole = lane_names.per_width("rg_vu")
    lines = [
        *_shuffle_macro(),
        f"static inline {lane_names.TARGET} __attribute__((unused)) void "
        f"{lane_names.per_width(f'rg_deinterleave{size}')}({v} *t, const {real} *p) {{",
        f"  {v} {', '.join(f'x{k}' for k in range(size))};",
        *(f"  x{k} = *(const {whole} *)(p + {k * w});" for k in range(size)),
    ]
    for e in range(size):
        source = [(l * size + e) // w for l in range(w)]
        lane = [(l * size + e) % w for l in range(w)]
        used = sorted(set(source))
        if len(used) == 1:
            mask = [lane[l] for l in range(w)]
            lines.append(f"  t[{e}] = RG_SHUFFLE(x{used[0]}, x{used[0]}, {', '.join(map(str, mask))});")
            continue
        # the first two sources, then each further one over what is gathered so far
        mask = [lane[l] if source[l] == used[0] else w + lane[l] if source[l] == used[1] else l for l in range(w)]
        lines.append(f"  t[{e}] = RG_SHUFFLE(x{used[0]}, x{used[1]}, {', '.join(map(str, mask))});")
        for k in used[2:]:
            mask = [w + lane[l] if source[l] == k else l for l in range(w)]
            lines.append(f"  t[{e}] = RG_SHUFFLE(t[{e}], x{k}, {', '.join(map(str, mask))});")
    lines += ["}", "#undef RG_SHUFFLE"]
    return lines


def width_close() -> str:
    """The end of one width's copy of the lane code: its names undefined, its guard closed."""
    names = (
        lane_names.VECTOR,
        lane_names.MASK_VECTOR,
        lane_names.WIDTH,
        lane_names.SPLAT,
        lane_names.TARGET,
        lane_names.PER_WIDTH,
    )
    return "\n".join(f"#undef {name}" for name in names) + "\n#endif\n"


def driver_source(prefix: str, kernel: Kernel, precision: Precision) -> str:
    """RG_L(rgb_<fn>): the whole blocks of W among n states through the lane kernel, each state
    checked as the single-state function checks it (status 1 and 3: its outputs untouched; 2:
    set to 0). Returns the status of the first state whose single call returns nonzero, or 0.
    Ports go in and out W elements of W states at a time through rg_gather and rg_scatter (a
    transpose in registers); a small input port by rg_deinterleave<size>. An output's elements
    past the last multiple of W go through rg_scatter_part; an input's through rg_gather, W
    whole elements read into the next states' where states follow the block (else
    rg_gather_part). The outputs of a block where a state fails its checks go one at a time."""
    real, v, w = precision.real, lane_names.VECTOR, lane_names.WIDTH
    zero = "0.0f" if real == "float" else "0.0"
    inputs, outputs = _array_ports(kernel), kernel.outputs
    params = [
        f"const {params_type(prefix)} *{p.name}" if is_parameter_port(p) else f"const {real} *{p.name}"
        for p in kernel.inputs
    ] + [f"{real} *{p.name}" for p in outputs]
    # an input's last size mod W elements are gathered whole, W of them, where the states after the
    # block hold what the loads read past them
    arrays = [f"rgb_in{k}[({p.size} + {w} - 1) / {w} * {w}]" for k, p in enumerate(inputs)] + [
        f"rgb_out{k}[{p.size}]" for k, p in enumerate(outputs)
    ]
    arguments, k = [], 0
    for p in kernel.inputs:
        if is_parameter_port(p):
            arguments.append(p.name)
        else:
            arguments.append(f"rgb_in{k}")
            k += 1
    arguments += [f"rgb_out{k}" for k in range(len(outputs))]
    step = any(p.name == STEP_PORT and p.size == 1 for p in kernel.inputs)
    checked = kernel.guarded or step
    gather, scatter = lane_names.per_width("rg_gather"), lane_names.per_width("rg_scatter")
    scatter_part, gather_part = lane_names.per_width("rg_scatter_part"), lane_names.per_width("rg_gather_part")
    lines = [
        f"/* {function_name(prefix, kernel)} on {w} states at a time, the whole blocks of n. */",
        f"static {lane_names.TARGET} int {lane_names.per_width(DRIVER + kernel.name)}(int n, {', '.join(params)}) {{",
        f"  {v} {', '.join(arrays)};",
        "  int rg_b, rg_e" + (f", rg_l, rg_s[{w}], rg_failed, rg_status = 0;" if checked else ";"),
        *([f"  {lane_names.MASK_VECTOR} rg_in, rg_out, rg_dt;", "  size_t rg_k;"] if checked else []),
        *([f"  {v} rg_x;"] if kernel.guarded else []),
        f"  for (rg_b = 0; rg_b <= n - {w}; rg_b += {w}) {{",
    ]
    for k, p in enumerate(inputs):
        widths = [width.lanes(precision) for width in WIDTHS if deinterleaved(p.size, width.lanes(precision))]
        if widths:
            lines += [
                f"#if {' || '.join(f'{w} == {n}' for n in widths)}",
                f"    {lane_names.per_width(f'rg_deinterleave{p.size}')}"
                f"(rgb_in{k}, {p.name} + (size_t)rg_b * {p.size});",
                "#else",
            ]
        lines += [
            f"    for (rg_e = 0; rg_e + {w} <= {p.size}; rg_e += {w})",
            f"      {gather}(rgb_in{k} + rg_e, {p.name} + (size_t)rg_b * {p.size} + rg_e, {p.size});",
            f"    if ({p.size} % {w} && rg_b + {w} + ({w} - {p.size} % {w} + {p.size} - 1) / {p.size} <= n)",
            f"      {gather}(rgb_in{k} + {p.size} - {p.size} % {w}, "
            f"{p.name} + (size_t)rg_b * {p.size} + {p.size} - {p.size} % {w}, {p.size});",
            f"    else if ({p.size} % {w})",
            f"      {gather_part}(rgb_in{k} + {p.size} - {p.size} % {w}, "
            f"{p.name} + (size_t)rg_b * {p.size} + {p.size} - {p.size} % {w}, {p.size}, {p.size} % {w});",
        ]
        if widths:
            lines.append("#endif")
    lines.append(f"    {lane_names.per_width('rgl_' + kernel.name)}({', '.join(arguments)});")
    fast = []
    for k, p in enumerate(outputs):
        fast += [
            f"for (rg_e = 0; rg_e + {w} <= {p.size}; rg_e += {w})",
            f"  {scatter}({p.name} + (size_t)rg_b * {p.size} + rg_e, {p.size}, rgb_out{k} + rg_e);",
            f"if ({p.size} % {w})",
            f"  {scatter_part}({p.name} + (size_t)rg_b * {p.size} + {p.size} - {p.size} % {w}, {p.size}, "
            f"rgb_out{k} + {p.size} - {p.size} % {w}, {p.size} % {w});",
        ]
    if not checked:
        lines += ["    " + line for line in fast]
        lines += ["  }", "  return 0;", "}"]
        return "\n".join(lines) + "\n"
    # the checks on whole vectors: x - x is 0 for a finite x and NaN for a NaN or an infinity
    mask = lane_names.MASK_VECTOR
    dt_port = next((k for k, p in enumerate(inputs) if p.name == STEP_PORT and p.size == 1), None)
    lines += [f"    rg_in = rg_out = rg_dt = ({mask}){{0}};"]
    if kernel.guarded:
        for side, ports in (("in", inputs), ("out", outputs)):
            for k, p in enumerate(ports):
                lines += [
                    f"    for (rg_e = 0; rg_e < {p.size}; ++rg_e) {{",
                    f"      rg_x = rgb_{side}{k}[rg_e] - rgb_{side}{k}[rg_e];",
                    f"      rg_{side} |= rg_x != rg_x;",
                    "    }",
                ]
    if step:
        lines.append(f"    rg_dt = rgb_in{dt_port}[0] <= {lane_names.splat(zero)};")
    lines += [
        "    rg_failed = 0;",
        f"    for (rg_l = 0; rg_l < {w}; ++rg_l) {{",
        "      rg_s[rg_l] = rg_in[rg_l] ? 1 : rg_dt[rg_l] ? 3 : rg_out[rg_l] ? 2 : 0;",
        "      rg_failed |= rg_s[rg_l];",
        "      if (rg_s[rg_l] != 0 && rg_status == 0) rg_status = rg_s[rg_l];",
        "    }",
        "    if (!rg_failed) {",
        *("      " + line for line in fast),
        "      continue;",
        "    }",
        f"    for (rg_l = 0; rg_l < {w}; ++rg_l) {{",
        "      rg_k = (size_t)(rg_b + rg_l);",
        "      if (rg_s[rg_l] == 0) {",
    ]
    lines += [
        f"        for (rg_e = 0; rg_e < {p.size}; ++rg_e) {p.name}[rg_k * {p.size} + rg_e] = rgb_out{k}[rg_e][rg_l];"
        for k, p in enumerate(outputs)
    ]
    if kernel.guarded:
        lines.append("      } else if (rg_s[rg_l] == 2) {")
        lines += [
            f"        for (rg_e = 0; rg_e < {p.size}; ++rg_e) {p.name}[rg_k * {p.size} + rg_e] = {zero};"
            for p in outputs
        ]
    lines += ["      }", "    }", "  }", "  return rg_status;", "}"]
    return "\n".join(lines) + "\n"


def select_source(precision: Precision, laned: bool = True) -> str:
    """rg_batch_width(lanes): the lanes a batch call uses, the widest this build and CPU have
    that is at most ``lanes`` (0 or less: no cap); 1 where no lanes are compiled (always, when
    not ``laned``)."""
    lines = [f"static int {SELECT}(int lanes) {{"]
    if not laned:
        return "\n".join([*lines, "  (void)lanes;", "  return 1;", "}"]) + "\n"
    for guard in dict.fromkeys(w.guard for w in WIDTHS):
        lines.append(f"#{'if' if guard == WIDTHS[0].guard else 'elif'} defined({guard})")
        if guard == X86:
            lines.append("  __builtin_cpu_init();")
        for width in (w for w in WIDTHS if w.guard == guard):
            n = width.lanes(precision)
            supported = f' && __builtin_cpu_supports("{width.cpu_feature}")' if width.cpu_feature else ""
            lines.append(f"  if ((lanes <= 0 || lanes >= {n}){supported}) return {n};")
    lines += ["#endif", "  (void)lanes;", "  return 1;", "}"]
    return "\n".join(lines) + "\n"


def batch_source(prefix: str, kernel: Kernel, precision: Precision, laned: bool = True) -> str:
    """The public ``<fn>_batch_lanes`` and ``<fn>_batch``: the widest block driver the CPU runs
    (at most ``lanes``), then the states left over one at a time (every state, when not
    ``laned``)."""
    whole, capped = batch_prototypes(prefix, kernel, precision)
    names = [p.name for p in (*kernel.inputs, *kernel.outputs)]
    single = [
        p.name if is_parameter_port(p) else f"{p.name} + (size_t)rg_k * {p.size}"
        for p in (*kernel.inputs, *kernel.outputs)
    ]
    lines = [capped + " {", "  int rg_k, rg_s, rg_status = 0, rg_done = 0;", f"  switch ({SELECT}(lanes)) {{"]
    for guard in dict.fromkeys(w.guard for w in WIDTHS) if laned else ():
        lines.append(f"#{'if' if guard == WIDTHS[0].guard else 'elif'} defined({guard})")
        for width in (w for w in WIDTHS if w.guard == guard):
            n = width.lanes(precision)
            lines += [
                f"  case {n}:",
                f"    rg_status = {DRIVER}{kernel.name}_{width.name}(n, {', '.join(names)});",
                f"    rg_done = n - n % {n};",
                "    break;",
            ]
    lines += [
        *(["#endif"] if laned else []),
        "  default:",
        "    break;",
        "  }",
        "  for (rg_k = rg_done; rg_k < n; ++rg_k) {",
        f"    rg_s = {function_name(prefix, kernel)}({', '.join(single)});",
        "    if (rg_s != 0 && rg_status == 0) rg_status = rg_s;",
        "  }",
        "  return rg_status;",
        "}",
        "",
        whole + " {",
        f"  return {batch_name(prefix, kernel)}_lanes(0, n, {', '.join(names)});",
        "}",
    ]
    return "\n".join(lines) + "\n"
