"""Run-time parameters in the emitted code: the `<name>_params` struct and its defaults in
the header, `const <name>_params *params` in the C kernels, keyword-only arguments in the
extension, the stub and the manifest. Kernels are built by hand with make_kernel and checked
against CasADi's own evaluation with the same parameter vector."""

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
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robotgen.emit import build
from robotgen.emit import compile as emit_compile
from robotgen.emit.sx_program import KernelError
from robotgen.model.parameters import RuntimeParameter
from robotgen.symbolic.kernel import PARAMS, Kernel, ParameterSymbols, Port, make_kernel

GCC = shutil.which("gcc")
CLANG = shutil.which("clang")
GXX = shutil.which("g++")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror"]
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is required")

# Struct order differs from name order on purpose (keywords are looked up by name).
PARAMETERS = [
    RuntimeParameter("gain", (), (2.5,), "Proportional gain [1/s^2]."),
    RuntimeParameter("damping", (3,), (0.1, -0.25, 0.3), "Per-axis damping [1/s]."),
    RuntimeParameter(
        "stiffness",
        (3, 3),
        (4.0, 0.5, -1.0, 0.25, 3.0, 0.125, -0.75, 1.5, 2.0),
        "Coupling matrix; element (i, j) couples axis i to axis j.",
    ),
]
DEFAULTS = {p.name: np.array(p.default).reshape(p.shape) if p.shape else p.default[0] for p in PARAMETERS}
SHAPES = {p.name: p.shape for p in PARAMETERS}

# a static object (not const) in C; a static function (code, like rg_sincos2) is not state
MUTABLE_STATIC = r"\bstatic\b(?!\s+const\b)(?![^;={(]*\()"


def parameter_kernels(parameters: list[RuntimeParameter] = PARAMETERS) -> list[Kernel]:
    """servo reads every parameter, fk none (so it has no port), gain_matrix only the
    parameters (no array input)."""
    symbols = ParameterSymbols.of(parameters)
    gain, damping = symbols.symbols["gain"], symbols.symbols["damping"]
    stiffness = ca.reshape(symbols.symbols["stiffness"], 3, 3).T  # the row-major field as a matrix
    q, qd = ca.SX.sym("q", 3), ca.SX.sym("qd", 3)
    tau = gain * ca.sin(stiffness @ q) - damping * qd + ca.cos(q[0]) * stiffness[1, 2]
    coupled = stiffness @ ca.diag(ca.tanh(qd)) + gain * ca.SX.eye(3)
    return [
        make_kernel(
            "servo",
            "A servo law that reads every run-time parameter.",
            [("q", q), ("qd", qd)],
            [("tau", tau, (3, 1)), ("coupled", coupled, (3, 3))],
            parameters=symbols,
        ),
        make_kernel(
            "fk",
            "Reads only q.",
            [("q", q)],
            [("y", ca.sin(q) * ca.cos(q[1]), (3, 1)), ("R", ca.cos(q @ q.T), (3, 3))],
            parameters=symbols,
        ),
        make_kernel(
            "gain_matrix",
            "Parameters only.",
            [],
            [("G", gain * stiffness + ca.diag(damping), (3, 3))],
            parameters=symbols,
        ),
    ]


KERNELS = parameter_kernels()
SERVO, FK, GAIN_MATRIX = KERNELS


def parameter_vector(**values) -> np.ndarray:
    """The PARAMS port's value: every parameter (the default unless given) row-major."""
    return np.concatenate([np.ravel(np.asarray(values.get(p.name, DEFAULTS[p.name]), float)) for p in PARAMETERS])


def reference(kernel: Kernel, args, **values) -> list[np.ndarray]:
    """CasADi's evaluation; the parameter vector is appended when the kernel has the port."""
    args = [np.asarray(a, float) for a in args]
    if kernel.inputs and kernel.inputs[-1].name == PARAMS:
        args.append(parameter_vector(**values))
    result = kernel.function(*args)
    result = result if isinstance(result, (list, tuple)) else [result]
    return [
        np.array(v, float).ravel().reshape((p.rows, p.cols) if p.is_matrix else (p.rows,))
        for v, p in zip(result, kernel.outputs)
    ]


def load_module(directory: Path, name: str):
    path = directory / (name + emit_compile.extension_suffix())
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def assert_close(actual, expected, rtol):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    scale = np.abs(expected).max(initial=1.0)
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * scale)


def as_tuple(value):
    return value if isinstance(value, tuple) else (value,)


def random_values(rng) -> dict:
    return {name: rng.normal(size=shape) if shape else float(rng.normal()) for name, shape in SHAPES.items()}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("params") / "pbot"
    build.emit(out, "pbot", KERNELS, nq=3, spec_sha256="cd" * 32)
    return out


@pytest.fixture(scope="module")
def module(built):
    return load_module(built, "pbot")


# ------------------------------------------------------------------------- the hand-over


def test_only_kernels_reading_a_parameter_get_the_port():
    assert [p.name for p in SERVO.inputs] == ["q", "qd", PARAMS]
    assert SERVO.inputs[-1].parameters == tuple(PARAMETERS) and SERVO.inputs[-1].size == 13
    assert [p.name for p in FK.inputs] == ["q"]
    assert [p.name for p in GAIN_MATRIX.inputs] == [PARAMS]


# ---------------------------------------------------------------------------- the header


def test_header_declares_the_struct_and_its_defaults(built):
    header = (built / "pbot.h").read_text()
    struct = header[header.index("typedef struct {") : header.index("} pbot_params;")]
    fields = re.findall(r"^    (double \w+(?:\[\d+\])?);$", struct, re.M)
    assert fields == ["double gain", "double damping[3]", "double stiffness[9]"]
    for p in PARAMETERS:
        assert p.doc in struct
    assert "shape (), default 2.5 */" in struct
    assert "shape (3,), default {0.1, -0.25, 0.3} */" in struct
    assert "shape (3, 3) row-major, default" in struct and "{4.0, 0.5, -1.0," in struct
    assert "#define PBOT_PARAMS_DEFAULT { \\" in header
    assert (
        "int pbot_servo(const double *q, const double *qd, const pbot_params *params, double *tau, double *coupled);"
    ) in header
    assert "int pbot_fk(const double *q, double *y, double *R);" in header
    assert "int pbot_gain_matrix(const pbot_params *params, double *G);" in header
    assert "PARAMS_SIZE" not in header  # the struct is not an array port
    source = (built / "pbot.c").read_text()
    assert "params->gain" in source and "params->damping[2]" in source
    assert "params->stiffness[8]" in source


def c_program(name: str, real: str, changes: dict) -> str:
    """Calls every kernel with the default struct, then with ``changes`` made to its fields,
    printing the outputs with full precision."""
    upper = name.upper()
    lines = [
        "#include <stdio.h>",
        f'#include "{name}.h"',
        "",
        f"static void print_values(const {real} *v, int n)",
        "{",
        "    int i;",
        "    for (i = 0; i < n; ++i) {",
        '        printf("%.17g\\n", (double)v[i]);',
        "    }",
        "}",
        "",
        f"static int run(const {name}_params *p)",
        "{",
        f"    const {real} q[3] = {{0.5, -1.25, 2.0}};",
        f"    const {real} qd[3] = {{-0.5, 0.75, 1.5}};",
        f"    {real} tau[{upper}_SERVO_TAU_SIZE], coupled[{upper}_SERVO_COUPLED_SIZE];",
        f"    {real} y[{upper}_FK_Y_SIZE], R[{upper}_FK_R_SIZE], G[{upper}_GAIN_MATRIX_G_SIZE];",
        f"    if ({name}_servo(q, qd, p, tau, coupled) != 0 || {name}_fk(q, y, R) != 0",
        f"        || {name}_gain_matrix(p, G) != 0) {{",
        "        return 1;",
        "    }",
        "    print_values(tau, 3);",
        "    print_values(coupled, 9);",
        "    print_values(y, 3);",
        "    print_values(R, 9);",
        "    print_values(G, 9);",
        "    return 0;",
        "}",
        "",
        "int main(void)",
        "{",
        f"    {name}_params p = {upper}_PARAMS_DEFAULT;",
        "    if (run(&p) != 0) {",
        "        return 1;",
        "    }",
    ]
    lines += [f"    p.{field} = {value!r};" for field, value in changes.items()]
    lines += ["    return run(&p);", "}", ""]
    return "\n".join(lines)


C_Q, C_QD = [0.5, -1.25, 2.0], [-0.5, 0.75, 1.5]
C_CHANGES = {"gain": -1.75, "damping[1]": 0.625, "stiffness[5]": -2.5}  # stiffness[5] is (1, 2)


def changed_values() -> dict:
    damping, stiffness = DEFAULTS["damping"].copy(), DEFAULTS["stiffness"].copy()
    damping[1], stiffness[1, 2] = 0.625, -2.5
    return {"gain": -1.75, "damping": damping, "stiffness": stiffness}


def expected_c_output(**values) -> np.ndarray:
    return np.concatenate(
        [
            np.ravel(v)
            for k, args in ((SERVO, [C_Q, C_QD]), (FK, [C_Q]), (GAIN_MATRIX, []))
            for v in reference(k, args, **values)
        ]
    )


@pytest.mark.parametrize("compiler", [GCC, CLANG], ids=["gcc", "clang"])
def test_c_program_agrees_with_casadi(built, tmp_path, compiler):
    if compiler is None:
        pytest.skip("clang not installed")
    (tmp_path / "main.c").write_text(c_program("pbot", "double", C_CHANGES))
    exe = tmp_path / "main"
    subprocess.run(
        [
            compiler,
            *STRICT,
            "-pedantic",
            "-O2",
            f"-I{built}",
            str(tmp_path / "main.c"),
            str(built / "pbot.c"),
            "-o",
            str(exe),
            "-lm",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    printed = np.array(
        [float(v) for v in subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()]
    )
    defaults, changed = np.split(printed, 2)
    assert_close(defaults, expected_c_output(), 1e-12)
    assert_close(changed, expected_c_output(**changed_values()), 1e-12)
    assert not np.allclose(defaults[:12], changed[:12])


@pytest.mark.skipif(GXX is None, reason="g++ not installed")
def test_header_compiles_as_cpp(built, tmp_path):
    (tmp_path / "main.cpp").write_text(c_program("pbot", "double", C_CHANGES))
    for standard in ("-std=c++98", "-std=c++11"):
        subprocess.run(
            [
                GXX,
                standard,
                "-Wall",
                "-Wextra",
                "-Werror",
                f"-I{built}",
                "-c",
                str(tmp_path / "main.cpp"),
                "-o",
                str(tmp_path / "main.o"),
            ],
            check=True,
            capture_output=True,
        )


def test_a_kernel_without_the_port_is_emitted_as_before(built, tmp_path):
    """fk, built with the module's parameters but reading none, prints exactly as in a module
    that has no parameters at all, and that module has no trace of them."""
    q = ca.SX.sym("q", 3)
    plain = make_kernel(
        "fk", "Reads only q.", [("q", q)], [("y", ca.sin(q) * ca.cos(q[1]), (3, 1)), ("R", ca.cos(q @ q.T), (3, 3))]
    )
    build.emit(tmp_path / "pbot", "pbot", [plain], nq=3, compile=False)
    before = (tmp_path / "pbot" / "pbot.c").read_text()
    definition = before[before.index("int pbot_fk(") :]
    assert definition in (built / "pbot.c").read_text()
    header = (tmp_path / "pbot" / "pbot.h").read_text()
    fk_block = header[header.index("/* pbot_fk:") : header.index("#ifdef __cplusplus\n}")]
    assert fk_block in (built / "pbot.h").read_text()
    for file in ("pbot.h", "pbot.c", "pbot_module.c", "pbot.pyi", "manifest.json"):
        assert "param" not in (tmp_path / "pbot" / file).read_text().lower(), file


def test_no_mutable_state_beyond_what_cpython_needs(built, tmp_path):
    for file in ("pbot.c", "pbot.h"):
        assert not re.search(MUTABLE_STATIC, (built / file).read_text())
    x = ca.SX.sym("x")
    build.emit(
        tmp_path / "plain", "plain", [make_kernel("f", "", [("x", x)], [("y", 2 * x, (1, 1))])], nq=1, compile=False
    )

    def mutable_globals(text):
        return {
            re.sub(r"\w+_", "", m)
            for m in re.findall(r"^static (?!const\b)[^(=;]*?\**(\w+)(?:\[[^]]*\])?\s*(?:=|;)", text, re.M)
        }

    found = mutable_globals((built / "pbot_module.c").read_text())
    assert found == mutable_globals((tmp_path / "plain" / "plain_module.c").read_text())
    assert found == {"keys", "methods", "module", "spare"}  # spare: each function's results to hand out again


# ----------------------------------------------------------------------- the Python module


def test_defaults_are_used_when_omitted(module):
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd = rng.normal(size=3), rng.normal(size=3)
        for got, expected in zip(module.servo(q, qd), reference(SERVO, [q, qd])):
            assert_close(got, expected, 1e-12)
        for got, expected in zip(module.fk(q), reference(FK, [q])):
            assert_close(got, expected, 1e-12)
    assert_close(module.gain_matrix(), reference(GAIN_MATRIX, [])[0], 1e-12)


def test_each_keyword_changes_the_result_as_casadi_predicts(module):
    rng = np.random.default_rng(2)
    q, qd = rng.normal(size=3), rng.normal(size=3)
    default_tau = module.servo(q, qd)[0]
    for name, value in random_values(rng).items():
        got = module.servo(q, qd, **{name: value})
        for g, e in zip(got, reference(SERVO, [q, qd], **{name: value})):
            assert_close(g, e, 1e-12)
        assert not np.allclose(got[0], default_tau), name
        assert_close(module.gain_matrix(**{name: value}), reference(GAIN_MATRIX, [], **{name: value})[0], 1e-12)
    values = random_values(rng)
    for g, e in zip(module.servo(q=q, qd=qd, **values), reference(SERVO, [q, qd], **values)):
        assert_close(g, e, 1e-12)
    # the defaults passed explicitly, lists, ints and 0-d arrays are all accepted
    explicit = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in DEFAULTS.items()}
    np.testing.assert_array_equal(module.servo(q, qd, **explicit)[0], default_tau)
    np.testing.assert_array_equal(module.servo(q, qd, gain=np.array(3.0))[0], module.servo(q, qd, gain=3)[0])
    np.testing.assert_array_equal(
        module.servo(q, qd, stiffness=np.asfortranarray(DEFAULTS["stiffness"]))[0], default_tau
    )


def test_batched_inputs_share_the_parameters(module):
    rng = np.random.default_rng(3)
    Q, QD, values = rng.normal(size=(4, 3)), rng.normal(size=(4, 3)), random_values(rng)
    tau, coupled = module.servo(Q, QD, **values)
    assert tau.shape == (4, 3) and coupled.shape == (4, 3, 3)
    for b in range(4):
        expected = reference(SERVO, [Q[b], QD[b]], **values)
        assert_close(tau[b], expected[0], 1e-12)
        assert_close(coupled[b], expected[1], 1e-12)
        np.testing.assert_array_equal(tau[b], module.servo(Q[b], QD[b], **values)[0])
    np.testing.assert_array_equal(module.servo(Q, QD)[0][2], module.servo(Q[2], QD[2])[0])


def test_signature_has_keyword_only_parameters_with_the_spec_defaults(module):
    signature = inspect.signature(module.servo)
    kinds = {name: p.kind for name, p in signature.parameters.items()}
    assert kinds == {
        "q": inspect.Parameter.POSITIONAL_OR_KEYWORD,
        "qd": inspect.Parameter.POSITIONAL_OR_KEYWORD,
        "gain": inspect.Parameter.KEYWORD_ONLY,
        "damping": inspect.Parameter.KEYWORD_ONLY,
        "stiffness": inspect.Parameter.KEYWORD_ONLY,
        "out": inspect.Parameter.KEYWORD_ONLY,
    }
    for name, default in DEFAULTS.items():
        np.testing.assert_array_equal(signature.parameters[name].default, default)
    assert list(inspect.signature(module.gain_matrix).parameters) == ["gain", "damping", "stiffness", "out"]
    assert list(inspect.signature(module.fk).parameters) == ["q", "out"]
    doc = module.servo.__doc__
    assert "gain: number, keyword-only, default 2.5. Proportional gain [1/s^2]." in doc
    assert "damping: float64 array (3,), keyword-only, default [0.1, -0.25, 0.3]." in doc
    assert "not batched" in doc


_Q, _QD = np.zeros(3), np.zeros(3)


@pytest.mark.parametrize(
    "call, kind, message",
    [
        (lambda m: m.servo(_Q, _QD, 1.0), TypeError, "servo() takes 2 positional arguments but 3 were given"),
        (lambda m: m.servo(_Q, _QD, 1.0, _QD, _QD), TypeError, "servo() takes 2 positional arguments but 5 were given"),
        (lambda m: m.gain_matrix(1.0), TypeError, "gain_matrix() takes 0 positional arguments but 1 was given"),
        (lambda m: m.servo(_Q, _QD, gian=1.0), TypeError, "servo() got an unexpected keyword argument 'gian'"),
        (lambda m: m.fk(_Q, gain=1.0), TypeError, "fk() got an unexpected keyword argument 'gain'"),
        (lambda m: m.servo(_Q, gain=1.0), TypeError, "servo() missing 1 required positional argument: 'qd'"),
        (
            lambda m: m.servo(_Q, _QD, gain=None),
            TypeError,
            "servo(): argument 'gain' must be a number (float64 of shape ()), got None",
        ),
        (
            lambda m: m.servo(_Q, _QD, damping=None),
            TypeError,
            "servo(): argument 'damping' must be a float64 array of shape (3,), got None",
        ),
        (
            lambda m: m.servo(_Q, _QD, stiffness="eye"),
            TypeError,
            "servo(): argument 'stiffness' must be a float64 array of shape (3, 3), got str",
        ),
        (
            lambda m: m.servo(_Q, _QD, gain={"a": 1}),
            TypeError,
            "servo(): argument 'gain' must be a number (float64 of shape ()), got dict: float() argument",
        ),
        (
            lambda m: m.servo(_Q, _QD, gain=[1.0, 2.0]),
            ValueError,
            "servo(): argument 'gain' must have shape () (a number), got (2,)",
        ),
        (
            lambda m: m.servo(_Q, _QD, damping=np.zeros(4)),
            ValueError,
            "servo(): argument 'damping' must have shape (3,), got (4,)",
        ),
        (
            lambda m: m.servo(_Q, _QD, damping=1.0),
            ValueError,
            "servo(): argument 'damping' must have shape (3,), got ()",
        ),
        (
            lambda m: m.servo(np.zeros((2, 3)), np.zeros((2, 3)), damping=np.zeros((2, 3))),
            ValueError,
            "servo(): argument 'damping' must have shape (3,), got (2, 3)",
        ),
        (
            lambda m: m.servo(_Q, _QD, stiffness=np.zeros(9)),
            ValueError,
            "servo(): argument 'stiffness' must have shape (3, 3), got (9,)",
        ),
        (
            lambda m: m.servo(_Q, _QD, stiffness=np.zeros((3, 3)).T[:2]),
            ValueError,
            "servo(): argument 'stiffness' must have shape (3, 3), got (2, 3)",
        ),
        (
            lambda m: m.gain_matrix(stiffness=[[1.0, 2.0], [3.0]]),
            ValueError,
            "gain_matrix(): argument 'stiffness' must be a float64 array of shape (3, 3), got list: ",
        ),
    ],
)
def test_argument_errors_name_the_argument(module, call, kind, message):
    with pytest.raises(kind) as caught:
        call(module)
    assert type(caught.value) is kind and str(caught.value).startswith(message), str(caught.value)


def test_errors_leak_no_references(module):
    q, d = np.zeros(3), np.zeros(3)
    bad = np.zeros(4)
    before = sys.getrefcount(q), sys.getrefcount(d), sys.getrefcount(bad)
    for _ in range(200):
        for call in (
            lambda: module.servo(q, q, damping=bad),
            lambda: module.servo(q, q, gain=None),
            lambda: module.servo(q, q, gian=d),
            lambda: module.servo(q, q, d),
            lambda: module.servo(q, q, stiffness=["x"] * 3),
        ):
            with pytest.raises((TypeError, ValueError)):
                call()
        module.servo(q, q, damping=d, gain=1.0)
    assert (sys.getrefcount(q), sys.getrefcount(d), sys.getrefcount(bad)) == before


def test_parameters_attribute_info_and_manifest(built, module):
    assert list(module.parameters) == ["gain", "damping", "stiffness"]
    assert type(module.parameters["gain"]) is float and module.parameters["gain"] == 2.5
    for name in ("damping", "stiffness"):
        value = module.parameters[name]
        assert value.dtype == np.float64 and value.shape == SHAPES[name]
        np.testing.assert_array_equal(value, DEFAULTS[name])
    q = np.ones(3)
    before = module.servo(q, q)[0]
    module.parameters["damping"][:] = 100.0  # documented: changes nothing the functions use
    module.parameters["gain"] = -1.0
    np.testing.assert_array_equal(module.servo(q, q)[0], before)
    assert "does not change the defaults" in module.__doc__
    expected = [
        {
            "name": p.name,
            "shape": list(p.shape),
            "doc": p.doc,
            "range": None,  # no bounds declared
            "default": np.array(p.default).reshape(p.shape).tolist(),
        }
        for p in PARAMETERS
    ]
    assert module.info()["parameters"] == expected
    assert "parameters" in module.info.__doc__
    manifest = json.loads((built / "manifest.json").read_text())
    assert manifest["parameters"] == expected
    assert {f["name"]: f["reads_parameters"] for f in manifest["functions"]} == {
        "servo": True,
        "fk": False,
        "gain_matrix": True,
    }
    assert [p["name"] for p in manifest["functions"][0]["inputs"]] == ["q", "qd"]


# --------------------------------------------------------------------------------- the stub


def test_stub_lists_the_keyword_only_parameters(built):
    tree = ast.parse((built / "pbot.pyi").read_text())
    variables = {node.target.id: ast.unparse(node.annotation) for node in tree.body if isinstance(node, ast.AnnAssign)}
    assert variables == {"nq": "int", "parameters": "dict[str, Any]"}
    functions = {node.name: node.args for node in tree.body if isinstance(node, ast.FunctionDef)}
    for name, positional in (("servo", ["q", "qd"]), ("gain_matrix", [])):
        arguments = functions[name]
        assert [a.arg for a in arguments.args] == positional
        assert [(a.arg, ast.unparse(a.annotation)) for a in arguments.kwonlyargs][:3] == [
            ("gain", "float"),
            ("damping", "npt.ArrayLike"),
            ("stiffness", "npt.ArrayLike"),
        ]
        assert [a.arg for a in arguments.kwonlyargs][3:] == ["out"]
        assert [ast.unparse(d) for d in arguments.kw_defaults] == ["..."] * 3 + ["None"]
    assert [a.arg for a in functions["fk"].kwonlyargs] == ["out"]


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed")
def test_mypy_checks_parameter_keywords(built, tmp_path):
    (tmp_path / "good.py").write_text(
        "import numpy as np\nimport pbot\n\n"
        "tau, C = pbot.servo(np.zeros(3), qd=[0.0, 1.0, 2.0], gain=1.5, damping=np.ones(3))\n"
        "G = pbot.gain_matrix(stiffness=np.eye(3), gain=2)\n"
        "defaults: dict[str, object] = pbot.parameters\n"
        "print(tau.shape, G.shape, defaults)\n"
    )
    (tmp_path / "bad.py").write_text(
        "import numpy as np\nimport pbot\n\n"
        "pbot.servo(np.zeros(3), np.zeros(3), gian=1.5)\n"
        "pbot.servo(np.zeros(3), np.zeros(3), 1.5)\n"
        "pbot.fk(np.zeros(3), gain=1.5)\n"
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
    assert 'bad.py:4: error: Unexpected keyword argument "gian" for "servo"' in result.stdout
    assert "bad.py:5: error: Too many positional arguments" in result.stdout
    assert 'bad.py:6: error: Unexpected keyword argument "gain" for "fk"' in result.stdout
    assert len(errors) == 3, result.stdout


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed")
def test_stub_agrees_with_the_runtime_module(built, tmp_path):
    env = {**os.environ, "MYPYPATH": str(built), "PYTHONPATH": str(built)}
    result = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "pbot"], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


# ---------------------------------------------------------------------------- float precision


def test_float_precision_agrees_to_single_precision(tmp_path):
    out = tmp_path / "pbotf"
    build.emit(out, "pbotf", KERNELS, nq=3, precision="float")
    header = (out / "pbotf.h").read_text()
    assert "    float gain;" in header and "    float stiffness[9];" in header and "2.5f, \\" in header
    assert "double" not in header + (out / "pbotf.c").read_text()
    (tmp_path / "main.c").write_text(c_program("pbotf", "float", C_CHANGES))
    subprocess.run(
        [
            GCC,
            *STRICT,
            "-pedantic",
            "-O2",
            f"-I{out}",
            str(tmp_path / "main.c"),
            str(out / "pbotf.c"),
            "-o",
            str(tmp_path / "main"),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    printed = np.array(
        [
            float(v)
            for v in subprocess.run([str(tmp_path / "main")], check=True, capture_output=True, text=True).stdout.split()
        ]
    )
    defaults, changed = np.split(printed, 2)
    assert_close(defaults, expected_c_output(), 1e-5)
    assert_close(changed, expected_c_output(**changed_values()), 1e-5)
    module = load_module(out, "pbotf")
    assert module.info()["precision"] == "float"
    assert module.parameters["gain"] == 2.5
    rng = np.random.default_rng(5)
    q, qd = rng.normal(size=3), rng.normal(size=3)
    for values in ({}, random_values(rng), {"gain": 0.1}):
        for got, expected in zip(module.servo(q, qd, **values), reference(SERVO, [q, qd], **values)):
            assert got.dtype == np.float64
            assert_close(got, expected, 1e-5)
    Q, QD = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    np.testing.assert_array_equal(module.servo(Q, QD, gain=0.5)[0][1], module.servo(Q[1], QD[1], gain=0.5)[0])
    with pytest.raises(ValueError, match=r"argument 'damping' must have shape \(3,\)"):
        module.servo(q, qd, damping=[1.0])


# ------------------------------------------------------------- broken hand-overs are refused


def _kernel_with(port: Port, name="k") -> Kernel:
    x, p = ca.SX.sym("x"), ca.SX.sym("p", port.size)
    return Kernel(name, "", (Port("x", 1), port), (Port("y", 1),), ca.Function("f", [x, p], [x * p[0]]))


def _port(parameters, name=PARAMS):
    return Port(name, sum(p.size for p in parameters), 1, tuple(parameters))


@pytest.mark.parametrize(
    "kernels, message",
    [
        ([_kernel_with(_port(PARAMETERS), "a"), _kernel_with(_port(PARAMETERS[:2]), "b")], "other run-time parameters"),
        ([_kernel_with(_port(PARAMETERS, name="extra"))], "ride only on the last input"),
        ([_kernel_with(Port(PARAMS, 12, 1, tuple(PARAMETERS)))], "its parameters hold 13"),
        ([_kernel_with(_port([RuntimeParameter("x", (), (1.0,), "")]))], "have the names of run-time parameters"),
        (
            [_kernel_with(_port([RuntimeParameter("a", (), (1.0,), ""), RuntimeParameter("a", (), (2.0,), "")]))],
            "names repeat",
        ),
        ([_kernel_with(_port([RuntimeParameter("NAN", (), (1.0,), "")]))], "reserved"),
        ([_kernel_with(_port([RuntimeParameter("for", (), (1.0,), "")]))], "identifier"),
        ([_kernel_with(_port([RuntimeParameter("a", (), (float("inf"),), "")]))], "finite"),
        ([_kernel_with(_port(PARAMETERS), PARAMS)], "clash with the C type bad_params"),
        ([_kernel_with(_port(PARAMETERS), "parameters")], "names repeat"),
    ],
)
def test_broken_parameter_hand_overs_are_internal_errors(tmp_path, kernels, message):
    with pytest.raises(KernelError, match=message):
        build.emit(tmp_path / "bad", "bad", kernels, nq=1, compile=False)
    assert not (tmp_path / "bad").exists()


def test_module_attribute_named_parameters_is_refused(tmp_path):
    with pytest.raises(KernelError, match="names repeat"):
        build.emit(
            tmp_path / "bad",
            "bad",
            [_kernel_with(_port(PARAMETERS))],
            nq=1,
            compile=False,
            attributes={"parameters": 1},
        )
    with pytest.raises(KernelError, match=r"extra_info may not set \['parameters'\]"):
        build.emit(
            tmp_path / "bad",
            "bad",
            [_kernel_with(_port(PARAMETERS))],
            nq=1,
            compile=False,
            extra_info={"parameters": []},
        )
