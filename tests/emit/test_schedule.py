"""Scheduled kernels (robotgen.symbolic.schedule): the emitted loops visit their index space in
the documented order, a body reads before it writes, and the product with M^-1 solves. Each is
compiled and run through the Python module and compared with numpy written independently."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robotgen.emit import build
from robotgen.emit import compile as emit_compile
from robotgen.emit.context import _count_scheduled
from robotgen.symbolic.kernel import make_kernel, row_major
from robotgen.symbolic.rigid_body.cholesky import (
    cholesky_factor,
    cholesky_substitute_columns,
    schedule_inverse_product,
)
from robotgen.symbolic.schedule import (
    ABOVE,
    ABOVE_DESCENDING,
    BELOW,
    DESCENDING,
    LOCAL,
    ONCE,
    OUTPUT,
    RANGE,
    ScheduleBuilder,
    Slice,
    body,
)

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is required")
N = 5
PAIR_SPACES = [BELOW, ABOVE, ABOVE_DESCENDING]


def _pairs_in_documented_order(space: str, n: int) -> list[tuple[int, int]]:
    """(i, j) as the schedule module's docstring states them, written out independently."""
    out = []
    if space == BELOW:
        for j in range(n):
            out += [(i, j) for i in range(j + 1, n)]
    elif space == ABOVE:
        for j in range(1, n):
            out += [(i, j) for i in range(j)]
    elif space == ABOVE_DESCENDING:
        for j in range(n - 1, 0, -1):
            out += [(i, j) for i in range(j)]
    return out


def _order_kernel():
    """Recurrences whose results depend on the visiting order of every index space."""
    x, y = ca.SX.sym("x", N), ca.SX.sym("y", N)
    outputs = [N + 1, N + 1] + [N * N] * len(PAIR_SPACES) + [N, 1]
    b = ScheduleBuilder([x, y], outputs)
    X, Y = b.local(x), b.local(y)
    PRE, SUF = b.local(size=N + 1), b.local(size=N + 1)
    b.prologue(Slice(LOCAL, PRE), ca.SX(1.0))
    b.prologue(Slice(LOCAL, SUF, N), ca.SX(0.0))
    E = b.local(ca.vertcat(x[0], y[1:]))
    S = b.local(ca.SX(0.25))
    prev, xi = ca.SX.sym("prev"), ca.SX.sym("xi")
    # prefix (RANGE) and suffix (DESCENDING) recurrences, each element reading the last
    b.loop(
        body("prefix", [prev, xi], [0.5 * prev + xi]),
        RANGE,
        N,
        [Slice(LOCAL, PRE, i_stride=1), Slice(LOCAL, X, i_stride=1)],
        [Slice(LOCAL, PRE, 1, i_stride=1)],
    )
    b.loop(
        body("suffix", [prev, xi], [0.7 * prev + xi]),
        DESCENDING,
        N,
        [Slice(LOCAL, SUF, 1, i_stride=1), Slice(LOCAL, Y, i_stride=1)],
        [Slice(LOCAL, SUF, i_stride=1)],
    )
    whole = ca.SX.sym("whole", N + 1)
    for k, array in enumerate((PRE, SUF)):
        b.loop(body("copy", [whole], [whole]), ONCE, 1, [Slice(LOCAL, array)], [Slice(OUTPUT, k)])
    # one running value through every pair space, written at (i, j)
    s, a, c = ca.SX.sym("s"), ca.SX.sym("a"), ca.SX.sym("c")
    step = 0.9 * s + a * c
    for k, space in enumerate(PAIR_SPACES):
        b.loop(
            body("pair_" + space.replace(" ", "_"), [s, a, c], [step, step]),
            space,
            N,
            [Slice(LOCAL, S), Slice(LOCAL, X, i_stride=1), Slice(LOCAL, Y, j_stride=1)],
            [Slice(LOCAL, S), Slice(OUTPUT, 2 + k, i_stride=N, j_stride=1)],
        )
    # a body whose write overlaps what it reads: swap neighbours, all reads first
    pair = ca.SX.sym("pair", 2)
    b.loop(
        body("swap", [pair], [ca.vertcat(pair[1], pair[0])]),
        RANGE,
        N - 1,
        [Slice(LOCAL, E, i_stride=1)],
        [Slice(LOCAL, E, i_stride=1)],
    )
    everything = ca.SX.sym("e", N)
    b.loop(body("copy", [everything], [everything]), ONCE, 1, [Slice(LOCAL, E)], [Slice(OUTPUT, 2 + len(PAIR_SPACES))])
    b.loop(body("total", [s], [s]), ONCE, 1, [Slice(LOCAL, S)], [Slice(OUTPUT, 3 + len(PAIR_SPACES))])
    names = ["prefix", "suffix", *(f"pairs_{space.replace(' ', '_')}" for space in PAIR_SPACES), "swapped", "total"]
    shapes = [(N + 1, 1), (N + 1, 1), *[(N, N)] * len(PAIR_SPACES), (N, 1), (1, 1)]
    values = [ca.reshape(v, shape[1], shape[0]).T for v, shape in zip(b.outputs(), shapes)]
    return make_kernel(
        "order", "Order-sensitive loops.", [("x", x), ("y", y)], list(zip(names, values, shapes)), schedule=b
    )


def _order_reference(x, y):
    prefix = [1.0]
    for i in range(N):
        prefix.append(0.5 * prefix[-1] + x[i])
    suffix = [0.0] * (N + 1)
    for i in reversed(range(N)):
        suffix[i] = 0.7 * suffix[i + 1] + y[i]
    s, pairs = 0.25, []
    for space in PAIR_SPACES:
        P = np.zeros((N, N))
        for i, j in _pairs_in_documented_order(space, N):
            s = 0.9 * s + x[i] * y[j]
            P[i, j] = s
        pairs.append(P)
    e = [x[0], *y[1:]]
    swapped = e[1:] + e[:1]  # neighbour swaps from the left carry the first element to the end
    return [np.array(prefix), np.array(suffix), *pairs, np.array(swapped), np.array([s])]


def _solve_kernel(n: int, width: int):
    m, r = ca.SX.sym("m", n * n), ca.SX.sym("r", n * width)
    b = ScheduleBuilder([m, r], [n * n, n * n])
    inverse = b.local(row_major(cholesky_substitute_columns(cholesky_factor(ca.reshape(m, n, n).T), ca.SX.eye(n))))
    rows = b.local(size=n * width)
    b.prologue(Slice(LOCAL, rows), r)
    schedule_inverse_product(b, n, inverse, rows, width, [((OUTPUT, 0), 0, 1.0), ((OUTPUT, 1), n, -2.0)])
    values = [ca.reshape(v, n, n).T for v in b.outputs()]
    return make_kernel(
        "solve",
        "M^-1 R, row by row.",
        [("m", m, (n, n)), ("r", r, (n, width))],
        [("first", values[0], (n, n)), ("second", values[1], (n, n))],
        schedule=b,
    )


def _staged_kernel(name: str, scale: float):
    """A running sum over a stage's outputs: sum_k<=i scale x_k^2 sin x_k."""
    x = ca.SX.sym("x", N)
    b = ScheduleBuilder([x], [N])
    SQUARES, SINES = b.stage("powers", [("squares", scale * x * x), ("sines", ca.sin(x))])
    TOTAL = b.local(size=N + 1)
    b.prologue(Slice(LOCAL, TOTAL), ca.SX(0.0))
    prev, square, sine = ca.SX.sym("prev"), ca.SX.sym("square"), ca.SX.sym("sine")
    b.loop(
        body("running", [prev, square, sine], [prev + square * sine]),
        RANGE,
        N,
        [Slice(LOCAL, TOTAL, i_stride=1), Slice(LOCAL, SQUARES, i_stride=1), Slice(LOCAL, SINES, i_stride=1)],
        [Slice(LOCAL, TOTAL, 1, i_stride=1)],
    )
    whole = ca.SX.sym("whole", N)
    b.loop(body("copy", [whole], [whole]), ONCE, 1, [Slice(LOCAL, TOTAL, 1)], [Slice(OUTPUT, 0)])
    return make_kernel(name, "A running sum over a stage.", [("x", x)], [("total", b.outputs()[0], (N, 1))], schedule=b)


def _load(directory: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, directory / (name + emit_compile.extension_suffix()))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def module(tmp_path_factory):
    out = tmp_path_factory.mktemp("scheduled") / "loops"
    kernels = [
        _order_kernel(),
        _solve_kernel(4, 8),
        _staged_kernel("staged", 1.0),
        _staged_kernel("again", 1.0),
        _staged_kernel("other", 2.0),
    ]
    build.emit(out, "loops", kernels, nq=1, spec_sha256="cd" * 32)
    return _load(out, "loops")


def test_loops_visit_each_index_space_in_the_documented_order(module):
    rng = np.random.default_rng(3)
    for _ in range(5):
        x, y = rng.normal(size=N), rng.normal(size=N)
        got = module.order(x, y)
        for actual, expected in zip(got, _order_reference(x, y)):
            np.testing.assert_allclose(np.ravel(actual), np.ravel(expected), rtol=1e-13, atol=1e-13)


def test_the_kernels_graph_is_the_schedule(module):
    """CasADi's evaluation of the flattened graph equals the compiled loops."""
    kernel = _order_kernel()
    x, y = np.linspace(-1, 1, N), np.cos(np.arange(N))
    flat = kernel.function(x, y)
    for actual, expected in zip(module.order(x, y), flat):
        np.testing.assert_allclose(np.ravel(actual), np.ravel(np.array(expected)), rtol=1e-13, atol=1e-13)


def test_inverse_product_against_numpy(module):
    rng = np.random.default_rng(7)
    for _ in range(20):
        A = rng.normal(size=(4, 4))
        M = A @ A.T + 0.1 * np.eye(4)
        R = rng.normal(size=(4, 8))
        first, second = module.solve(M, R)
        X = np.linalg.solve(M, R)
        np.testing.assert_allclose(first, X[:, :4], rtol=1e-10, atol=1e-10 * np.abs(X).max())
        np.testing.assert_allclose(second, -2 * X[:, 4:], rtol=1e-10, atol=1e-10 * np.abs(X).max())


def test_operation_count_counts_each_iteration():
    kernel = _solve_kernel(4, 8)
    arithmetic, _ = _count_scheduled(kernel)
    # the product alone: per row and column 4 multiplies and 3 additions
    assert arithmetic >= 4 * 8 * (4 + 3)


def test_a_stage_is_one_helper_for_every_kernel_that_repeats_it(module):
    """Two kernels with the same stage call one static helper; a different stage of the same
    name gets a helper of its own. The results are those of numpy."""
    source = (Path(module.__file__).parent / "loops.c").read_text()
    assert source.count("static void rg_powers(const double *x, double *squares, double *sines) {") == 1
    assert source.count("static void rg_powers_2(const double *x, double *squares, double *sines) {") == 1
    assert source.count("  rg_powers(x, ") == 2 and source.count("  rg_powers_2(x, ") == 1
    x = np.linspace(-1.2, 0.9, N)
    for name, scale in (("staged", 1.0), ("again", 1.0), ("other", 2.0)):
        np.testing.assert_allclose(getattr(module, name)(x), np.cumsum(scale * x * x * np.sin(x)), rtol=1e-14)


def test_a_stages_operations_count_once_per_call():
    arithmetic, sin_cos = _count_scheduled(_staged_kernel("staged", 2.0))
    # stage: 2 multiplies and a sine per element (the sines are operations too); loop: a multiply and an add
    assert (arithmetic, sin_cos) == (5 * N, N)
