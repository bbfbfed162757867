"""robotgen.emit: printed C, compiled extension, manifest and atomic output, checked against
CasADi's own evaluation of kernels built directly with casadi (no specs involved)."""

from __future__ import annotations

import ast
import importlib.util
import inspect
import json
import os
import re
import shutil
import subprocess
import sys
import weakref
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robotgen.emit import build, c_kernel
from robotgen.emit import compile as emit_compile
from robotgen.emit.c_kernel import OPERATIONS
from robotgen.emit.sx_program import KernelError
from robotgen.errors import OutputError
from robotgen.symbolic.kernel import Kernel, Port

GCC = shutil.which("gcc")
CLANG = shutil.which("clang")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror"]
SOURCES = [
    "{name}.h",
    "{name}.c",
    "{name}_module.c",
    "{name}.pyi",
    "Makefile",
    "{name}.pc.in",
    "{name}Config.cmake.in",
    "manifest.json",
]
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is required")

# a static object (not const) in C; a static function (code, like rg_sincos2) is not state
MUTABLE_STATIC = r"\bstatic\b(?!\s+const\b)(?![^;={(]*\()"


# ---------------------------------------------------------------- kernels built with casadi


def _bounded(x):
    return 0.9 * ca.tanh(x)


UNARY = [
    ca.sin,
    ca.cos,
    ca.tanh,
    ca.atan,
    ca.fabs,
    ca.erf,
    ca.sign,
    ca.floor,
    ca.ceil,
    ca.asinh,
    lambda x: -x,
    lambda x: x**2,
    lambda x: 2 * x,
    lambda x: ca.constpow(x, 3),
    lambda x: ca.sqrt(x * x + 1),
    lambda x: ca.log(x * x + 1),
    lambda x: ca.exp(ca.tanh(x)),
    lambda x: 1 / (1.5 + ca.sin(x)),
    lambda x: ca.asin(_bounded(x)),
    lambda x: ca.acos(_bounded(x)),
    lambda x: ca.atanh(_bounded(x)),
    lambda x: ca.tan(_bounded(x)),
    lambda x: ca.sinh(_bounded(x)),
    lambda x: ca.cosh(_bounded(x)),
    lambda x: ca.acosh(1 + x * x),
    lambda x: ca.log1p(x * x),
    lambda x: ca.expm1(_bounded(x)),
]
BINARY = [
    lambda a, b: a + b,
    lambda a, b: a - b,
    lambda a, b: a * b,
    lambda a, b: a / (1 + b * b),
    ca.atan2,
    ca.fmin,
    ca.fmax,
    ca.hypot,
    ca.copysign,
    lambda a, b: ca.power(ca.fabs(a) + 0.5, ca.tanh(b)),
    lambda a, b: ca.if_else(a > b, a, b * b),
    lambda a, b: ca.fmod(a, ca.fabs(b) + 1),
    lambda a, b: ca.remainder(a, ca.fabs(b) + 1),
    lambda a, b: ca.logic_and(a < b, a != b) * a + ca.logic_or(a <= b, a == b) * b,
    lambda a, b: ca.logic_not(a > b) * (a + 0.1),
]


def random_expression(rng, leaves, depth):
    if depth == 0 or rng.random() < 0.15:
        return leaves[rng.integers(len(leaves))] if rng.random() < 0.85 else ca.SX(rng.normal())
    if rng.random() < 0.5:
        return UNARY[rng.integers(len(UNARY))](random_expression(rng, leaves, depth - 1))
    op = BINARY[rng.integers(len(BINARY))]
    return op(random_expression(rng, leaves, depth - 1), random_expression(rng, leaves, depth - 1))


def make_kernel(name, seed, inputs=(("q", 3), ("qd", 2)), outputs=(("y", 4, 1), ("M", 3, 3)), depth=6):
    """A random nonlinear kernel; matrix outputs leave flattened row-major."""
    rng = np.random.default_rng(seed)
    symbols = [ca.SX.sym(port, size) for port, size in inputs]
    leaves = [s[i] for s in symbols for i in range(s.numel())]
    columns = []
    for _, rows, cols in outputs:
        matrix = ca.SX(rows, cols)
        for r in range(rows):
            for c in range(cols):
                matrix[r, c] = random_expression(rng, leaves, depth)
        columns.append(ca.vec(matrix.T))
    function = ca.Function(name, symbols, columns)
    return Kernel(
        name,
        f"Random kernel {name} (seed {seed}).",
        tuple(Port(p, n) for p, n in inputs),
        tuple(Port(p, r, c) for p, r, c in outputs),
        function,
    )


def every_operation_kernel():
    x = ca.SX.sym("x", 3)
    a, b, c = x[0], x[1], x[2]
    exprs = [
        a + b,
        a - b,
        a * b,
        a / b,
        -a,
        a**2,
        2 * a,
        1 / a,
        ca.sqrt(ca.fabs(a)),
        ca.exp(a),
        ca.log(ca.fabs(a)),
        ca.power(ca.fabs(a), b),
        ca.constpow(a, 3.5),
        ca.sin(a),
        ca.cos(a),
        ca.tan(a),
        ca.asin(_bounded(a)),
        ca.acos(_bounded(a)),
        ca.atan(a),
        ca.atan2(a, b),
        ca.sinh(a),
        ca.cosh(a),
        ca.tanh(a),
        ca.asinh(a),
        ca.acosh(ca.fabs(a) + 1),
        ca.atanh(_bounded(a)),
        ca.fabs(a),
        ca.sign(a),
        ca.copysign(a, b),
        ca.fmin(a, b),
        ca.fmax(a, b),
        ca.floor(a),
        ca.ceil(a),
        ca.fmod(a, b),
        ca.remainder(a, b),
        ca.if_else(a < b, a, c),
        a < b,
        a <= b,
        a == b,
        a != b,
        ca.logic_not(a),
        ca.logic_and(a, b),
        ca.logic_or(a, b),
        ca.erf(a),
        ca.log1p(ca.fabs(a)),
        ca.expm1(a),
        ca.hypot(a, b),
        ca.inf * a,
        1e300 * 1e300,
        0.1 + a,
    ]
    function = ca.Function("every_op", [x], [ca.vertcat(*exprs)])
    return Kernel("every_op", "Each printable operation once.", (Port("x", 3),), (Port("y", len(exprs)),), function)


def planar_arm_kernels():
    """Smooth robot-like kernels: a 3-link planar arm's pose, Jacobian and J^T J + I."""
    q = ca.SX.sym("q", 3)
    lengths = (0.4, 0.3, 0.2)
    angle, x, y = 0, 0, 0
    for i, length in enumerate(lengths):
        angle = angle + q[i]
        x, y = x + length * ca.cos(angle), y + length * ca.sin(angle)
    pose = ca.SX.eye(4)
    pose[0, 0], pose[0, 1], pose[1, 0], pose[1, 1] = ca.cos(angle), -ca.sin(angle), ca.sin(angle), ca.cos(angle)
    pose[0, 3], pose[1, 3] = x, y
    jac = ca.jacobian(ca.vertcat(x, y, angle), q)
    mass = jac.T @ jac + ca.SX.eye(3)
    flat = lambda m: ca.vec(m.T)  # noqa: E731
    return [
        Kernel("fk", "Tip pose.", (Port("q", 3),), (Port("T", 4, 4),), ca.Function("fk", [q], [flat(pose)])),
        Kernel(
            "jacobian",
            "Planar Jacobian.",
            (Port("q", 3),),
            (Port("J", 3, 3),),
            ca.Function("jacobian", [q], [flat(jac)]),
        ),
        Kernel("mass", "J^T J + I.", (Port("q", 3),), (Port("M", 3, 3),), ca.Function("mass", [q], [flat(mass)])),
    ]


def special_kernels():
    x = ca.SX.sym("x", 2)
    unused = ca.SX.sym("unused", 3)
    sparse = ca.SX(4, 1)
    sparse[1] = ca.sin(x[0])
    sparse[3] = x[1] * 2.5
    return [
        Kernel(
            "unused_input",
            "Ignores its second input.",
            (Port("x", 2), Port("unused", 3)),
            (Port("out", 2),),
            ca.Function("u", [x, unused], [ca.cos(x)]),
        ),
        Kernel(
            "constant",
            "Returns constants only.",
            (Port("x", 2),),
            (Port("c", 3),),
            ca.Function("c", [x], [ca.DM([1.5, -2.0, 1e-300])]),
        ),
        Kernel(
            "sparse_out",
            "Structural zeros in the output.",
            (Port("x", 2),),
            (Port("s", 2, 2),),
            ca.Function("s", [x], [sparse]),
        ),
    ]


KERNELS = [
    make_kernel("rand_a", 1),
    make_kernel("rand_b", 2, outputs=(("m", 2, 3),)),
    make_kernel("rand_c", 3, inputs=(("u", 4),), outputs=(("v", 5, 1),), depth=7),
    every_operation_kernel(),
    *special_kernels(),
]


def reference(kernel, args):
    """CasADi's own evaluation, shaped per Port."""
    values = kernel.function(*[np.asarray(a, float) for a in args])
    values = values if isinstance(values, (list, tuple)) else [values]
    return [
        np.array(v, float).ravel().reshape(p.rows, p.cols) if p.is_matrix else np.array(v, float).ravel()
        for v, p in zip(values, kernel.outputs)
    ]


def random_args(kernel, rng, batch=None):
    lead = () if batch is None else (batch,)
    return [rng.normal(size=lead + ((p.rows, p.cols) if p.is_matrix else (p.rows,))) * 1.5 for p in kernel.inputs]


def load_module(directory: Path, name: str):
    path = directory / (name + emit_compile.extension_suffix())
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def assert_close(actual, expected, rtol):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    scale = np.where(np.isfinite(expected), np.abs(expected), 0).max(initial=1.0)
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * scale, equal_nan=True)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("double") / "randbot"
    build.emit(
        out,
        "randbot",
        KERNELS,
        nq=3,
        spec_sha256="ab" * 32,
        extra_info={"nodes": ["arm"]},
        attributes={"dt": 0.001, "tool": "gripper"},
    )
    return out


@pytest.fixture(scope="module")
def module(built):
    return load_module(built, "randbot")


# ------------------------------------------------------------------ (a) C compiles strictly


@pytest.mark.parametrize("extra", [[], ["-DNDEBUG", "-O2"], ["-O3", "-pedantic"]])
def test_source_compiles_warning_free_with_gcc(built, tmp_path, extra):
    subprocess.run(
        [GCC, *STRICT, *extra, "-c", str(built / "randbot.c"), "-o", str(tmp_path / "randbot.o")],
        check=True,
        capture_output=True,
    )


@pytest.mark.skipif(CLANG is None, reason="clang not installed")
def test_source_compiles_warning_free_with_clang(built, tmp_path):
    subprocess.run(
        [CLANG, *STRICT, "-O2", "-c", str(built / "randbot.c"), "-o", str(tmp_path / "randbot.o")],
        check=True,
        capture_output=True,
    )


def test_makefile_builds_static_library(built, tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make not installed")
    copy = shutil.copytree(built, tmp_path / "copy")
    subprocess.run(["make", "-C", str(copy)], check=True, capture_output=True)
    assert (copy / "librandbot.a").is_file()


# ---------------------------------------------------------- (b) a C harness agrees with casadi


def harness_source(name, kernels):
    lines = [
        "#include <stdio.h>",
        f'#include "{name}.h"',
        "",
        "static int read_values(FILE *f, double *v, int n)",
        "{",
        "    int i;",
        "    for (i = 0; i < n; ++i) {",
        '        if (fscanf(f, "%lf", &v[i]) != 1) {',
        "            return -1;",
        "        }",
        "    }",
        "    return 0;",
        "}",
        "",
        "static void print_values(const double *v, int n)",
        "{",
        "    int i;",
        "    for (i = 0; i < n; ++i) {",
        '        printf("%.17g\\n", v[i]);',
        "    }",
        "}",
        "",
        "int main(int argc, char **argv)",
        "{",
        "    FILE *f;",
        "    int samples, s;",
        '    if (argc != 2 || (f = fopen(argv[1], "r")) == NULL) {',
        "        return 2;",
        "    }",
        '    if (fscanf(f, "%d", &samples) != 1) {',
        "        return 3;",
        "    }",
        "    for (s = 0; s < samples; ++s) {",
    ]
    for k in kernels:
        ports = [*k.inputs, *k.outputs]
        lines.append("        {")
        lines += [f"            double {p.name}[{p.size}];" for p in ports]
        lines += [f"            if (read_values(f, {p.name}, {p.size}) != 0) return 4;" for p in k.inputs]
        lines.append(f"            if ({name}_{k.name}({', '.join(p.name for p in ports)}) != 0) return 5;")
        lines += [f"            print_values({p.name}, {p.size});" for p in k.outputs]
        lines.append("        }")
    lines += ["    }", "    fclose(f);", "    return 0;", "}", ""]
    return "\n".join(lines)


def run_harness(built, tmp_path, name, kernels, samples):
    (tmp_path / "harness.c").write_text(harness_source(name, kernels))
    exe = tmp_path / "harness"
    subprocess.run(
        [
            GCC,
            *STRICT,
            "-O2",
            f"-I{built}",
            str(tmp_path / "harness.c"),
            str(built / f"{name}.c"),
            "-o",
            str(exe),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    values = [str(len(samples))]
    for args in samples:
        for k_args in args:
            values += [repr(float(v)) for a in k_args for v in np.ravel(a)]
    (tmp_path / "inputs.txt").write_text("\n".join(values) + "\n")
    result = subprocess.run([str(exe), str(tmp_path / "inputs.txt")], check=True, capture_output=True, text=True)
    numbers = iter(float(v) for v in result.stdout.split())
    return [[[np.array([next(numbers) for _ in range(p.size)]) for p in k.outputs] for k in kernels] for _ in samples]


def test_c_harness_agrees_with_casadi(built, tmp_path):
    rng = np.random.default_rng(7)
    samples = [[random_args(k, rng) for k in KERNELS] for _ in range(20)]
    outputs = run_harness(built, tmp_path, "randbot", KERNELS, samples)
    for sample_args, sample_out in zip(samples, outputs):
        for kernel, args, got in zip(KERNELS, sample_args, sample_out):
            for value, expected in zip(got, reference(kernel, args)):
                assert_close(value, expected.ravel(), 1e-12)


# --------------------------------------------------------- (c) the Python module agrees too


def test_module_agrees_with_casadi_and_c_harness(built, module, tmp_path):
    rng = np.random.default_rng(11)
    samples = [[random_args(k, rng) for k in KERNELS] for _ in range(10)]
    c_outputs = run_harness(built, tmp_path, "randbot", KERNELS, samples)
    for sample_args, sample_c in zip(samples, c_outputs):
        for kernel, args, c_values in zip(KERNELS, sample_args, sample_c):
            got = getattr(module, kernel.name)(*args)
            got = got if isinstance(got, tuple) else (got,)
            assert len(got) == len(kernel.outputs)
            for value, expected, c_value, port in zip(got, reference(kernel, args), c_values, kernel.outputs):
                assert value.shape == expected.shape == ((port.rows, port.cols) if port.is_matrix else (port.rows,))
                assert_close(value, expected, 1e-12)
                np.testing.assert_array_equal(value.ravel(), c_value)


@pytest.mark.parametrize("batch", [1, 5])
def test_batch_equals_looping_single_calls(module, batch):
    rng = np.random.default_rng(batch)
    for kernel in KERNELS:
        fn = getattr(module, kernel.name)
        args = random_args(kernel, rng, batch)
        got = fn(*args)
        got = got if isinstance(got, tuple) else (got,)
        for j, port in enumerate(kernel.outputs):
            assert got[j].shape[0] == batch
            for b in range(batch):
                single = fn(*[a[b] for a in args])
                single = single if isinstance(single, tuple) else (single,)
                np.testing.assert_array_equal(got[j][b], single[j])


def test_empty_batch_and_argument_conversion(module):
    kernel = KERNELS[0]
    assert module.rand_a(np.zeros((0, 3)), np.zeros((0, 2)))[1].shape == (0, 3, 3)
    q = np.asfortranarray(np.arange(6.0).reshape(3, 2))[:, 0]  # strided view
    expected = module.rand_a(np.ascontiguousarray(q), np.array([1.0, 2.0]))
    for got in (module.rand_a(q, [1, 2]), module.rand_a(list(q), np.array([1, 2]))):
        for g, e in zip(got, expected):
            np.testing.assert_array_equal(g, e)
    assert kernel.name == "rand_a"


@pytest.mark.parametrize(
    "args, message",
    [
        ((np.zeros(4), np.zeros(2)), r"rand_a\(\): argument 'q' must have shape \(3,\) or \(B, 3\), got \(4,\)"),
        ((np.zeros((2, 3)), np.zeros((3, 2))), r"batch lengths differ: 'q' has 2, 'qd' has 3"),
        ((np.zeros((1, 2, 3)), np.zeros(2)), r"argument 'q' must have shape"),
        ((np.zeros(()), np.zeros(2)), r"argument 'q' must have shape"),
    ],
)
def test_wrong_shapes_raise_value_error(module, args, message):
    with pytest.raises(ValueError, match=message):
        module.rand_a(*args)


def test_an_argument_without_batch_axis_applies_to_every_point(module):
    rng = np.random.default_rng(5)
    Q, qd = rng.normal(size=(4, 3)), rng.normal(size=2)
    batched = module.rand_a(Q, qd)
    for k in range(4):
        for got, one in zip(batched, module.rand_a(Q[k], qd)):
            np.testing.assert_array_equal(got[k], one)
    for got, expected in zip(module.rand_a(Q[1], np.tile(qd, (3, 1))), module.rand_a(np.tile(Q[1], (3, 1)), qd)):
        np.testing.assert_array_equal(got, expected)


def test_wrong_argument_count_raises_type_error(module):
    with pytest.raises(TypeError, match=r"rand_a\(\) missing 1 required positional argument: 'qd'"):
        module.rand_a(np.zeros(3))


# ------------------------------------------------- keyword arguments and argument errors


def test_keyword_calls_equal_positional_calls(module):
    rng = np.random.default_rng(21)
    for kernel in KERNELS:
        fn = getattr(module, kernel.name)
        names = [p.name for p in kernel.inputs]
        for batch in (None, 3):
            args = random_args(kernel, rng, batch)
            positional = fn(*args)
            positional = positional if isinstance(positional, tuple) else (positional,)
            if batch is None:
                for value, expected in zip(positional, reference(kernel, args)):
                    assert_close(value, expected, 1e-12)
            by_name = dict(zip(names, args))
            calls = [
                fn(**by_name),
                fn(**dict(reversed(by_name.items()))),
                fn(args[0], **dict(list(by_name.items())[1:])),
            ]
            for got in calls:
                got = got if isinstance(got, tuple) else (got,)
                assert len(got) == len(positional)
                for g, e in zip(got, positional):
                    np.testing.assert_array_equal(g, e)


def test_signature_is_positional_or_keyword_then_out(module):
    for kernel in KERNELS:
        parameters = inspect.signature(getattr(module, kernel.name)).parameters
        assert list(parameters) == [p.name for p in kernel.inputs] + ["out"]
        assert [p.kind for p in parameters.values()] == [inspect.Parameter.POSITIONAL_OR_KEYWORD] * len(
            kernel.inputs
        ) + [inspect.Parameter.KEYWORD_ONLY]
        assert parameters["out"].default is None


# --------------------------------------------------- out=: results written into given arrays


def _results_like(value):
    return tuple(np.full_like(v, np.nan) for v in value) if isinstance(value, tuple) else np.full_like(value, np.nan)


@pytest.mark.parametrize("batch", [None, 4])
def test_out_receives_the_results_and_is_returned(module, batch):
    rng = np.random.default_rng(31)
    for kernel in KERNELS:
        fn = getattr(module, kernel.name)
        args = random_args(kernel, rng, batch)
        expected = fn(*args)
        out = _results_like(expected)
        got = fn(*args, out=out)
        if isinstance(expected, tuple):
            assert got is not out and len(got) == len(out)
            assert all(g is o for g, o in zip(got, out))
        else:
            assert got is out
        for g, e in zip(*(v if isinstance(v, tuple) else (v,) for v in (out, expected))):
            np.testing.assert_array_equal(g, e)
        for g, e in zip(*(v if isinstance(v, tuple) else (v,) for v in (fn(*args, out=None), expected))):
            np.testing.assert_array_equal(g, e)


def test_out_as_keyword_with_keyword_arguments(module):
    q, qd = np.linspace(-1, 1, 3), np.array([0.3, -0.2])
    y, m = module.rand_a(q, qd)
    out = (np.empty(4), np.empty((3, 3)))
    module.rand_a(qd=qd, out=out, q=q)
    np.testing.assert_array_equal(out[0], y)
    np.testing.assert_array_equal(out[1], m)


_Y, _M, _BUFFER = np.empty(4), np.empty((3, 3)), np.empty(9)


@pytest.mark.parametrize(
    "call, kind, message",
    [
        (
            lambda m: m.rand_a(_Q, _QD, out=_Y),
            TypeError,
            "rand_a(): out must be a tuple of 2 float64 arrays (one per result), got numpy.ndarray",
        ),
        (lambda m: m.rand_a(_Q, _QD, out=(_Y,)), TypeError, "rand_a(): out must be a tuple of 2"),
        (
            lambda m: m.rand_a(_Q, _QD, out=[_Y, _M]),
            TypeError,
            "rand_a(): out must be a tuple of 2 float64 arrays (one per result), got list",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(_Y, np.empty((3, 3), np.float32))),
            TypeError,
            "rand_a(): out[1] must be a float64 numpy array for 'M', got an array of another dtype",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(_Y, [[0.0] * 3] * 3)),
            TypeError,
            "rand_a(): out[1] must be a float64 numpy array for 'M', got list",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(_Y, np.empty((3, 4)))),
            ValueError,
            "rand_a(): out for 'M' must have shape (3, 3), got (3, 4)",
        ),
        (
            lambda m: m.rand_a(np.zeros((2, 3)), _QD, out=(_Y, _M)),
            ValueError,
            "rand_a(): out for 'y' must have shape (B, 4) (B of the batched arguments), got (4,)",
        ),
        (
            lambda m: m.rand_a(np.zeros((2, 3)), _QD, out=(np.empty((3, 4)), np.empty((2, 3, 3)))),
            ValueError,
            "rand_a(): out for 'y' must have shape (B, 4) (B of the batched arguments), got (3, 4)",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(_Y, np.empty((3, 3)).T)),
            ValueError,
            "rand_a(): out for 'M' must be writeable, aligned and C-contiguous",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(np.empty(8)[::2], _M)),
            ValueError,
            "rand_a(): out for 'y' must be writeable, aligned and C-contiguous",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(np.frombuffer(bytes(32)), _M)),
            ValueError,
            "rand_a(): out for 'y' must be writeable, aligned and C-contiguous",
        ),
        (
            lambda m: m.rand_a(_Q, _QD, out=(_M.reshape(-1)[:4], _M)),
            ValueError,
            "rand_a(): out for 'M' shares memory with out for 'y'",
        ),
        (
            lambda m: m.rand_c(_BUFFER[:4], out=_BUFFER[3:8]),
            ValueError,
            "rand_c(): out for 'v' shares memory with the argument 'u'",
        ),
        (lambda m: m.rand_c(_BUFFER[:4], out=_BUFFER[4:9]), None, None),  # adjacent, not shared: valid
    ],
)
def test_wrong_out_is_refused_naming_it(module, call, kind, message):
    if kind is None:  # a valid out, for contrast
        call(module)
        return
    with pytest.raises(kind) as caught:
        call(module)
    assert str(caught.value).startswith(message), str(caught.value)


def test_out_leaks_no_references(module):
    q, qd, y, m = np.zeros(3), np.zeros(2), np.zeros(4), np.zeros((3, 3))
    before = [sys.getrefcount(a) for a in (q, qd, y, m)]
    for _ in range(200):
        module.rand_a(q, qd, out=(y, m))
        with pytest.raises(ValueError):
            module.rand_a(q, qd, out=(y, y))
        with pytest.raises(TypeError):
            module.rand_a(q, qd, out=(y, m, m))
    assert [sys.getrefcount(a) for a in (q, qd, y, m)] == before


def _states(count: int, seed: int = 5):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(count, 3)), rng.normal(size=(count, 2))


def test_a_servo_loop_reuses_the_results_it_has_let_go(module):
    Q, QD = _states(12)
    expected = module.rand_a(Q, QD)  # a batch call: new arrays, never reused
    seen = set()
    y = M = None
    for k in range(len(Q)):
        y, M = module.rand_a(Q[k], QD[k])  # y, M hold the previous results while the call runs
        np.testing.assert_array_equal(y, expected[0][k])
        np.testing.assert_array_equal(M, expected[1][k])
        assert M.flags.writeable and M.flags.c_contiguous and M.flags.owndata
        seen.add(id(M))
    assert len(seen) == 2  # after the first two calls, the one before the previous is filled anew


def test_results_a_caller_holds_are_never_written_again(module):
    Q, QD = _states(6)
    expected = module.rand_a(Q, QD)
    kept = [module.rand_a(Q[k], QD[k]) for k in range(len(Q))]
    row = module.rand_a(Q[0], QD[0])[1][0]  # a view keeps its base
    _, M = module.rand_a(Q[1], QD[1])
    ref = weakref.ref(M)
    del M
    for k in range(len(Q)):
        module.rand_a(Q[k], QD[k])
    for k, (y, M) in enumerate(kept):
        np.testing.assert_array_equal(y, expected[0][k])
        np.testing.assert_array_equal(M, expected[1][k])
    np.testing.assert_array_equal(row, expected[1][0][0])
    assert ref() is None  # let go with only a weak reference: freed, not handed out again


@pytest.mark.parametrize(
    "change",
    [
        lambda M: setattr(M, "shape", (9,)),
        lambda M: setattr(M.flags, "writeable", False),
    ],
)
def test_a_result_changed_before_it_was_let_go_is_not_handed_out(module, change):
    Q, QD = _states(4)
    expected = module.rand_a(Q, QD)
    _, M = module.rand_a(Q[0], QD[0])
    change(M)
    del M
    for k in range(len(Q)):
        _, M = module.rand_a(Q[k], QD[k])
        assert M.shape == (3, 3) and M.flags.writeable
        np.testing.assert_array_equal(M, expected[1][k])


_Q, _QD = np.zeros(3), np.zeros(2)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda m: m.rand_a(), "rand_a() missing 2 required positional arguments: 'q' and 'qd'"),
        (lambda m: m.rand_a(qd=_QD), "rand_a() missing 1 required positional argument: 'q'"),
        (lambda m: m.rand_a(_Q), "rand_a() missing 1 required positional argument: 'qd'"),
        (lambda m: m.rand_a(_Q, _QD, _QD), "rand_a() takes 2 positional arguments but 3 were given"),
        (lambda m: m.rand_c(_Q, _Q), "rand_c() takes 1 positional argument but 2 were given"),
        (lambda m: m.rand_a(_Q, _QD, x=_Q), "rand_a() got an unexpected keyword argument 'x'"),
        (lambda m: m.rand_a(q=_Q, qd=_QD, Q=_Q), "rand_a() got an unexpected keyword argument 'Q'"),
        (lambda m: m.rand_a(_Q, _QD, q=_Q), "rand_a() got multiple values for argument 'q'"),
        (lambda m: m.rand_a(_Q, qd=_QD, q=_Q), "rand_a() got multiple values for argument 'q'"),
        (lambda m: m.rand_c(_Q, _Q, u=_Q), "rand_c() takes 1 positional argument but 2 were given"),
        (
            lambda m: m.rand_a(None, _QD),
            "rand_a(): argument 'q' must be a float64 array of shape (3,) or (B, 3), got None",
        ),
        (
            lambda m: m.rand_a(_Q, qd=None),
            "rand_a(): argument 'qd' must be a float64 array of shape (2,) or (B, 2), got None",
        ),
        (
            lambda m: m.rand_b("1.5", _QD),
            "rand_b(): argument 'q' must be a float64 array of shape (3,) or (B, 3), got str",
        ),
        (
            lambda m: m.rand_c(u=b"1234"),
            "rand_c(): argument 'u' must be a float64 array of shape (4,) or (B, 4), got bytes",
        ),
        (
            lambda m: m.rand_a(_Q, {"a": 1}),
            "rand_a(): argument 'qd' must be a float64 array of shape (2,) or (B, 2), got dict: "
            "float() argument must be a string or a real number, not 'dict'",
        ),
        (
            lambda m: m.rand_a(_Q, np.zeros(2, complex)),
            "rand_a(): argument 'qd' must be a float64 "
            "array of shape (2,) or (B, 2), got numpy.ndarray: Cannot cast array data",
        ),
    ],
)
def test_argument_errors_raise_type_error(module, call, message):
    with pytest.raises(TypeError) as caught:
        call(module)
    assert str(caught.value).startswith(message)


def test_unconvertible_values_raise_value_error_naming_the_argument(module):
    with pytest.raises(ValueError) as caught:
        module.rand_a(["a", "b", "c"], _QD)
    assert str(caught.value) == (
        "rand_a(): argument 'q' must be a float64 array of shape (3,) or "
        "(B, 3), got list: could not convert string to float: 'a'"
    )
    assert isinstance(caught.value.__cause__, ValueError)
    with pytest.raises(ValueError, match=r"argument 'qd' must be a float64 array .* got list: "):
        module.rand_a(_Q, [[1.0, 2.0], [3.0]])


def test_argument_errors_leak_no_references(module):
    q, qd = np.zeros(3), np.zeros(2)
    before = sys.getrefcount(q), sys.getrefcount(qd)
    for _ in range(200):
        for call in (
            lambda: module.rand_a(q, qd=qd, x=q),
            lambda: module.rand_a(q, qd, q=q),
            lambda: module.rand_a(q),
            lambda: module.rand_a(q, qd=None),
            lambda: module.rand_a(q, ["x", "y"]),
        ):
            with pytest.raises((TypeError, ValueError)):
                call()
        module.rand_a(q=q, qd=qd)
    assert (sys.getrefcount(q), sys.getrefcount(qd)) == before


# ------------------------------------------------------------------------- the .pyi stub


def test_stub_declares_every_function_attribute_and_signature(built, module):
    tree = ast.parse((built / "randbot.pyi").read_text())
    assert ast.get_docstring(tree).startswith("randbot: robot functions generated by robotgen")
    functions = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert sorted(functions) == sorted([k.name for k in KERNELS] + ["info"])
    variables = {node.target.id: ast.unparse(node.annotation) for node in tree.body if isinstance(node, ast.AnnAssign)}
    assert variables == {"nq": "int", "dt": "Any", "tool": "Any"}
    assert ast.unparse(functions["info"].returns) == "dict[str, Any]"
    array = "npt.NDArray[np.float64]"
    for kernel in KERNELS:
        node = functions[kernel.name]
        arguments = node.args
        assert not (arguments.posonlyargs or arguments.vararg or arguments.kwarg or arguments.defaults)
        assert [a.arg for a in arguments.args] == [p.name for p in kernel.inputs]
        assert [a.arg for a in arguments.kwonlyargs] == ["out"]
        assert list(inspect.signature(getattr(module, kernel.name)).parameters) == [a.arg for a in arguments.args] + [
            "out"
        ]
        assert {ast.unparse(a.annotation) for a in arguments.args} == {"npt.ArrayLike"}
        expected = array if len(kernel.outputs) == 1 else f"tuple[{', '.join([array] * len(kernel.outputs))}]"
        assert ast.unparse(node.returns) == expected
        assert ast.unparse(arguments.kwonlyargs[0].annotation) == f"{expected} | None"
        assert ast.unparse(arguments.kw_defaults[0]) == "None"
        assert ast.get_docstring(node) == kernel.doc.strip()


def test_stub_docstrings_are_escaped(tmp_path):
    x = ca.SX.sym("x")
    kernel = Kernel(
        "odd",
        'Says "hi" \\ with \u00e9 and """ quotes\tand tabs.\n\nSecond paragraph.',
        (Port("x", 1),),
        (Port("y", 1),),
        ca.Function("f", [x], [2 * x]),
    )
    build.emit(tmp_path / "odd", "odd", [kernel], nq=1, compile=False)
    tree = ast.parse((tmp_path / "odd" / "odd.pyi").read_text(encoding="ascii"))
    assert (
        ast.get_docstring(tree.body[-1], clean=False) == 'Says "hi" \\ with \u00e9 and """ quotes and tabs.'
    )  # one line, whitespace collapsed


def test_stub_names_are_reserved(tmp_path):
    x = ca.SX.sym("x")
    kernel = Kernel("np", "", (Port("x", 1),), (Port("y", 1),), ca.Function("f", [x], [x]))
    with pytest.raises(KernelError, match="reserved"):
        build.emit(tmp_path / "bad", "bad", [kernel], nq=1, compile=False)


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed")
def test_mypy_checks_calls_against_the_stub(built, tmp_path):
    (tmp_path / "good.py").write_text(
        "import numpy as np\nimport randbot\n\n"
        "y, M = randbot.rand_a(q=np.zeros(3), qd=[1.0, 2.0])\n"
        "m: float = float(randbot.rand_b(np.zeros(3), qd=np.zeros(2))[0, 0])\n"
        "n: int = randbot.nq + len(randbot.info())\n"
        "print(randbot.dt, y.shape, M.shape)\n"
    )
    (tmp_path / "bad.py").write_text(
        "import numpy as np\nimport randbot\n\n"
        "randbot.rand_a(np.zeros(3), qdd=np.zeros(2))\n"
        "randbot.rand_c()\n"
        "y: int = randbot.rand_c(np.zeros(4))\n"
    )
    env = {**os.environ, "MYPYPATH": str(built)}
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--cache-dir", os.devnull, "good.py", "bad.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert not [e for e in errors if e.startswith("good.py")], result.stdout
    bad = "\n".join(e for e in errors if e.startswith("bad.py"))
    assert 'bad.py:4: error: Unexpected keyword argument "qdd" for "rand_a"' in bad, result.stdout
    assert 'bad.py:5: error: Missing positional argument "u" in call to "rand_c"' in bad
    assert "bad.py:6: error: Incompatible types in assignment" in bad
    assert len(errors) == 3, result.stdout


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed")
def test_stub_agrees_with_the_runtime_module(built, tmp_path):
    """mypy's stubtest imports the extension and compares every name and signature."""
    env = {**os.environ, "MYPYPATH": str(built), "PYTHONPATH": str(built)}
    result = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "randbot"], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_module_attributes_and_info(module):
    info = module.info()
    assert info == {
        "name": "randbot",
        "nq": 3,
        "nodes": ["arm"],
        "functions": [k.name for k in KERNELS],
        "robotgen_version": info["robotgen_version"],
        "spec_sha256": "ab" * 32,
        "precision": "double",
    }
    module.info()["nq"] = 99
    assert module.info()["nq"] == 3 == module.nq
    assert (module.dt, module.tool) == (0.001, "gripper")
    assert str(inspect.signature(module.rand_a)) == "(q, qd, *, out=None)"
    assert module.rand_a.__doc__.startswith("Random kernel rand_a")


def test_manifest(built):
    manifest = json.loads((built / "manifest.json").read_text())
    assert manifest["name"] == "randbot" and manifest["casadi_version"] == ca.__version__
    assert manifest["precision"] == "double" and manifest["nq"] == 3
    by_name = {f["name"]: f for f in manifest["functions"]}
    assert by_name["rand_a"]["outputs"] == [{"name": "y", "shape": [4]}, {"name": "M", "shape": [3, 3]}]
    assert by_name["every_op"]["sin_cos_ops"] == 2
    assert by_name["constant"]["arithmetic_ops"] == 0
    assert all(f["arithmetic_ops"] > 10 for f in manifest["functions"] if f["name"].startswith("rand"))


def test_every_operation_is_printed():
    kernel = every_operation_kernel()
    f = kernel.function
    used = {f.instruction_id(k) for k in range(f.n_instructions())}
    untested = {op for op in OPERATIONS if op not in used} - {ca.OP_ASSIGN}
    assert not untested


# ------------------------------------------------------------ (d) determinism, (e) atomicity


def test_emitting_twice_is_byte_identical(tmp_path):
    first, second = tmp_path / "a" / "bot", tmp_path / "b" / "elsewhere"
    build.emit(first, "bot", KERNELS[:2], nq=3, compile=False)
    build.emit(second, "bot", KERNELS[:2], nq=3, compile=False)
    again = {f: (first / f.format(name="bot")).read_bytes() for f in SOURCES}
    build.emit(first, "bot", KERNELS[:2], nq=3, compile=False)
    for f in SOURCES:
        text = (first / f.format(name="bot")).read_bytes()
        assert text == again[f] == (second / f.format(name="bot")).read_bytes()
        assert str(tmp_path).encode() not in text
    assert sorted(p.name for p in tmp_path.joinpath("a").iterdir()) == ["bot"]


def test_failed_emit_leaves_nothing_behind(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("compiler exploded")

    monkeypatch.setattr(emit_compile, "compile_extension", broken)
    with pytest.raises(RuntimeError, match="exploded"):
        build.emit(tmp_path / "bot", "bot", KERNELS[:1], nq=3)
    assert list(tmp_path.iterdir()) == []


def test_failed_emit_keeps_previous_output(tmp_path, monkeypatch):
    out = tmp_path / "bot"
    build.emit(out, "bot", KERNELS[:1], nq=3, compile=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr(emit_compile, "compile_extension", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("boom")))
    with pytest.raises(RuntimeError, match="boom"):
        build.emit(out, "bot", KERNELS[:2], nq=3)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["bot"]


def test_refuses_to_replace_a_foreign_directory(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match="is not a robotgen output"):
        build.emit(tmp_path / "mine", "bot", KERNELS[:1], nq=3, compile=False)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"


def test_compiler_errors_carry_the_compiler_output(tmp_path):
    (tmp_path / "bad.c").write_text("int broken(void) { return; }\n")
    with pytest.raises(emit_compile.CompileError, match="bad.c"):
        emit_compile.compile_extension(tmp_path, "bad", ["bad.c"])


# ------------------------------------------------------------------------ (f) float precision


def test_float_precision_agrees_to_single_precision(tmp_path):
    kernels = planar_arm_kernels()
    out = tmp_path / "armf"
    build.emit(out, "armf", kernels, nq=3, precision="float")
    source = (out / "armf.c").read_text()
    assert "float *q" in source and "sinf(" in source and "double" not in source
    subprocess.run(
        [GCC, *STRICT, "-O2", "-c", str(out / "armf.c"), "-o", str(tmp_path / "a.o")], check=True, capture_output=True
    )
    module = load_module(out, "armf")
    assert module.info()["precision"] == "float"
    rng = np.random.default_rng(3)
    for kernel in kernels:
        for _ in range(20):
            q = rng.uniform(-np.pi, np.pi, 3)
            got = getattr(module, kernel.name)(q)
            assert got.dtype == np.float64
            np.testing.assert_array_equal(getattr(module, kernel.name)(q=q), got)
            assert_close(got, reference(kernel, [q])[0], 1e-5)
        batch = rng.uniform(-np.pi, np.pi, (4, 3))
        np.testing.assert_array_equal(getattr(module, kernel.name)(batch)[2], getattr(module, kernel.name)(batch[2]))


# ------------------------------------------------------------- (g) no state, heap or I/O in C


def test_c_library_has_no_mutable_statics_heap_or_io(built):
    for file in ("randbot.c", "randbot.h"):
        text = (built / file).read_text()
        assert not re.search(MUTABLE_STATIC, text)
        assert not re.search(r"\b(malloc|calloc|realloc|free|printf|fprintf|puts|fopen)\b", text)


# ------------------------------------------------------------------- internal errors are clear


def test_unprintable_operation_is_an_internal_error(tmp_path):
    x = ca.SX.sym("x")
    kernel = Kernel("inv_erf", "", (Port("x", 1),), (Port("y", 1),), ca.Function("f", [x], [ca.erfinv(x)]))
    with pytest.raises(KernelError, match="OP_ERFINV"):
        build.emit(tmp_path / "bad", "bad", [kernel], nq=1, compile=False)
    assert not (tmp_path / "bad").exists()


_X, _MX, _FREE = ca.SX.sym("x"), ca.MX.sym("x"), ca.SX.sym("free")
_IDENTITY = ca.Function("f", [_X], [_X])


@pytest.mark.parametrize(
    "kernel, message",
    [
        (Kernel("mx", "", (Port("x", 1),), (Port("y", 1),), ca.Function("f", [_MX], [2 * _MX])), "SX Function"),
        (
            Kernel(
                "free", "", (Port("x", 1),), (Port("y", 1),), ca.Function("f", [_X], [_X * _FREE], {"allow_free": True})
            ),
            "free symbols",
        ),
        (
            Kernel("shape", "", (Port("x", 1),), (Port("y", 2, 2),), ca.Function("f", [_X], [ca.SX.zeros(2, 2)])),
            "flattened row-major",
        ),
        (Kernel("count", "", (Port("x", 1), Port("z", 1)), (Port("y", 1),), _IDENTITY), "1 inputs"),
        (Kernel("w1", "", (Port("w1", 1),), (Port("y", 1),), _IDENTITY), "reserved"),
        (Kernel("names", "", (Port("sin", 1),), (Port("y", 1),), _IDENTITY), "reserved"),
        (Kernel("same", "", (Port("y", 1),), (Port("y", 1),), _IDENTITY), "repeat"),
        (Kernel("info", "", (Port("x", 1),), (Port("y", 1),), _IDENTITY), "repeat"),
        (Kernel("bad-name", "", (Port("x", 1),), (Port("y", 1),), _IDENTITY), "identifier"),
    ],
)
def test_broken_kernels_are_internal_errors(tmp_path, kernel, message):
    with pytest.raises(KernelError, match=message):
        build.emit(tmp_path / "bad", "bad", [kernel], nq=1, compile=False)


def test_long_runs_of_one_value_are_printed_as_fill_loops():
    """Stores at constant indices (c_kernel.Store, as the printer makes them) of one value into
    FILL_RUN or more consecutive elements become a loop; anything else is printed as it is."""
    n, Store = c_kernel.FILL_RUN, c_kernel.Store
    run = [Store("t3", k, "w0") for k in range(4, 4 + n)]
    short = [Store("out", k, "0.0") for k in range(n - 1)]
    broken = [Store("t1", k, f"w{k % 2}") for k in range(2 * n)]  # the value alternates
    gap = [Store("t2", k, "1e-05") for k in (*range(10), *range(11, 12 + n))]  # t2[10] is missing
    other = [Store("t4", k, "w0") for k in range(n // 2)] + [Store("t5", k, "w0") for k in range(n // 2, n)]
    assert c_kernel.fills(["w0 = 0.0;", *run, "w1 = w0 + q[0];"]) == [
        "w0 = 0.0;",
        f"for (int rg_e = 4; rg_e < {4 + n}; rg_e += 2) {{ t3[rg_e] = w0; t3[rg_e + 1] = w0; }}",
        "w1 = w0 + q[0];",
    ]
    assert c_kernel.fills(short) == [f"out[{k}] = 0.0;" for k in range(n - 1)]
    assert c_kernel.fills(broken) == [f"t1[{k}] = w{k % 2};" for k in range(2 * n)]
    assert c_kernel.fills(other) == list(map(str, other))  # consecutive indices, another array
    # n + 1 stores from t2[11]: a loop over n (two a step), then the last store
    assert c_kernel.fills(gap) == list(map(str, gap[:10])) + [
        f"for (int rg_e = 11; rg_e < {11 + n}; rg_e += 2) {{ t2[rg_e] = 1e-05; t2[rg_e + 1] = 1e-05; }}",
        f"t2[{11 + n}] = 1e-05;",
    ]


@pytest.mark.parametrize("real", ["double", "float"])
def test_the_ports_a_kernel_does_not_name_are_cast_to_void(real):
    """The unused-port casts come from the program, not from the printed text: a port named
    like a piece of a literal (e of 1e-05, f of 2.5f) is still cast when unread, and every port
    read or written is not."""
    x, e, f = ca.SX.sym("x", 2), ca.SX.sym("e"), ca.SX.sym("f")
    function = ca.Function("k", [x, e, f], [x[0] * 1e-05 + 2.5, ca.SX(0)])
    kernel = Kernel("k", "", (Port("x", 2), Port("e", 1), Port("f", 1)), (Port("y", 1), Port("z", 1)), function)
    source = c_kernel.kernel_source("m", kernel, c_kernel.PRECISIONS[real])
    casts = [line.strip() for line in source.splitlines() if line.strip().startswith("(void)")]
    assert casts == ["(void)e;", "(void)f;"]  # y is written, z zeroed, x read
    assert "e-05" in source and ("2.5f" in source) == (real == "float")
