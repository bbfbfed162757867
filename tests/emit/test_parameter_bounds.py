"""Run-time parameters are range-checked when set, from their declared Bounds
(robotgen.model.parameters): a value the spec may not hold is refused at run time with the
message `robotgen check` gives for it in a spec, through every way of setting it (a
function's keyword, a controller's constructor, `parameters[name] = `, `parameters = {...}`),
and `<name>_params_check` in C finds the same field. The C check and the Python one are
separate code: random values, many of them outside, must be judged alike."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robotgen.emit import build
from robotgen.emit import compile as emit_compile
from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.model.laws import force
from robotgen.model.laws.hand import FORGETTING, Q_MATRIX, R_MATRIX, TORQUE_WEIGHT, WEIGHT
from robotgen.model.laws.hand import GAIN as HAND_GAIN
from robotgen.model.parameter_struct import KF_INTERNAL, KI_INTERNAL
from robotgen.model.parameters import Bounds, RuntimeParameter
from robotgen.model.system import DAMPING, GAIN, GAIN_MATRIX, PAYLOAD_MASS
from robotgen.symbolic.kernel import ParameterSymbols, make_kernel

ROOT = Path(__file__).resolve().parents[2]
RMAC = ROOT / "specs" / "puma560_rmac.yaml"
HIGH = ROOT / "specs" / "styx_high_ct.yaml"
GCC = shutil.which("gcc")
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is required")

# The laws' own bounds, on parameters of the shapes they take, plus an interval of each kind.
PARAMETERS = [
    RuntimeParameter("mu", (), (0.99,), "forgetting", FORGETTING),
    RuntimeParameter("w", (4,), (1.0, 2.0, 3.0, 4.0), "diagonal weights", WEIGHT),
    RuntimeParameter("Q", (3, 3), (2.0, 0.5, 0.0, 0.5, 2.0, 0.0, 0.0, 0.0, 1.0), "a weight matrix", Q_MATRIX),
    RuntimeParameter("K", (2, 3), (1.0,) * 6, "gains", GAIN),
    RuntimeParameter("c", (), (0.0,), "damping", DAMPING),
    RuntimeParameter("a", (), (0.5,), "an interval", Bounds("fraction", minimum=-1.0, maximum=1.0)),
    RuntimeParameter("free", (2,), (-3.0, 1e30), "any number"),
]
SHAPES = {p.name: p.shape for p in PARAMETERS}


def load_module(directory: Path, name: str):
    path = directory / (name + emit_compile.extension_suffix())
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module", params=["double", "float"])
def toy(request, tmp_path_factory):
    """A module whose one function reads every parameter (their sum), and its directory."""
    name = f"bounded_{request.param}"
    out = tmp_path_factory.mktemp("bounds") / name
    symbols = ParameterSymbols.of(PARAMETERS)
    x = ca.SX.sym("x", 1)
    total = x + sum((ca.sum1(symbols.symbols[p.name]) for p in PARAMETERS[:-1]), ca.SX(0))
    kernel = make_kernel(
        "total", "x plus every bounded parameter's entries.", [("x", x)], [("y", total, (1, 1))], parameters=symbols
    )
    build.emit(out, name, [kernel], nq=1, spec_sha256="ab" * 32, precision=request.param)
    return load_module(out, name), out, request.param


def expected_message(parameter: RuntimeParameter, value) -> str | None:
    """What the module says: "argument 'name'" (with the entry) and Bounds.violation's message."""
    violation = parameter.bounds.violation(np.reshape(value, parameter.shape))
    if violation is None:
        return None
    entry = ""
    if (
        parameter.shape
        and violation.index
        and not (parameter.bounds.positive_definite and len(violation.index) == 2 and "symmetric" in violation.message)
    ):
        entry = "[" + ", ".join(map(str, violation.index)) + "]"
    return f"total(): argument '{parameter.name}'{entry}: {violation.message}"


CASES = [
    ("mu", 2.0, "argument 'mu': forgetting factor 2 must be in (0, 1] (eq 37)"),
    ("mu", 0.0, "argument 'mu': forgetting factor 0 must be in (0, 1] (eq 37)"),
    ("mu", float("nan"), "argument 'mu': forgetting factor nan must be finite (eq 37)"),
    ("w", [1.0, 2.0, -0.5, 1.0], "argument 'w'[2]: weight -0.5 must be positive"),
    (
        "K",
        [[1, 1, 1], [1, 0, 1]],
        "argument 'K'[1, 1]: gain 0 must be positive (the gain matrix must be positive definite)",
    ),
    ("c", -1e-3, "argument 'c': damping kv_internal -0.001 must be at least 0"),
    ("a", -1.5, "argument 'a': fraction -1.5 must be in [-1, 1]"),
    (
        "Q",
        [[1, 0, 0], [0.5, 1, 0], [0, 0, 1]],
        "argument 'Q': Q must be symmetric (eq 38): entry (0, 1) = 0 but (1, 0) = 0.5",
    ),
    (
        "Q",
        [[1, 2, 0], [2, 1, 0], [0, 0, 1]],
        "argument 'Q': Q must be positive definite (eq 38): its smallest eigenvalue is -1",
    ),
    ("Q", [[1, 0, 0], [0, np.inf, 0], [0, 0, 1]], "argument 'Q'[1, 1]: Q entry inf must be finite (eq 38)"),
]


@pytest.mark.parametrize("name, value, message", CASES)
def test_a_value_outside_is_refused_however_it_is_set(toy, name, value, message):
    module = toy[0]
    parameter = next(p for p in PARAMETERS if p.name == name)
    assert expected_message(parameter, value) == f"total(): {message}"  # the model says the same
    with pytest.raises(ValueError) as caught:
        module.total(0.0, **{name: value})
    assert str(caught.value) == f"total(): {message}"
    assert float(module.total(0.0)[0]) == pytest.approx(sum(sum(p.default) for p in PARAMETERS[:-1]), rel=1e-6)


def test_free_parameters_take_any_number(toy):
    module = toy[0]
    assert np.isfinite(module.total(1.0, free=[-1e300, 0.0])[0])


def test_the_c_check_and_the_model_judge_random_values_alike(toy):
    """Values near and across every bound (and asymmetric or indefinite matrices): the module
    refuses exactly those the model does, with the model's message."""
    module, _, precision = toy
    rng = np.random.default_rng(33)
    refused = 0
    for _ in range(400):
        parameter = PARAMETERS[rng.integers(len(PARAMETERS) - 1)]
        if parameter.shape == (3, 3):
            A = rng.normal(size=(3, 3))
            value = A @ A.T + rng.choice([-1.5, 0.0, 0.5]) * np.eye(3)
            if rng.random() < 0.3:
                value[rng.integers(3), rng.integers(3)] += rng.choice([0.25, 1e-14])
        else:
            value = rng.choice([-1.0, -1e-300, 0.0, 1e-300, 0.5, 1.0, 1.0 + 1e-9, 3.0], size=parameter.shape)
        if precision == "float":  # the check reads the value in the module's precision
            value = np.asarray(value, np.float32).astype(float)
        expected = expected_message(parameter, value)
        try:
            module.total(0.0, **{parameter.name: value})
            got = None
        except ValueError as error:
            got = str(error)
        if precision == "float" and expected and "eigenvalue" in expected:  # factored in single precision
            assert got is not None and "must be positive definite (eq 38): its smallest eigenvalue" in got
        else:
            assert got == expected, (parameter.name, value)
        refused += got is not None
    assert 100 < refused < 350  # both kinds were tried


def test_a_failed_set_leaves_the_values_as_they_were(toy):
    module = toy[0]
    before = module.total(2.0, mu=0.5)
    with pytest.raises(ValueError):
        module.total(2.0, mu=0.5, w=[1.0, 1.0, 1.0, -1.0])
    assert module.total(2.0, mu=0.5) == before


def test_params_check_in_c_names_the_first_field_outside(toy, tmp_path):
    """<name>_params_check: 0 for the defaults, else 1 + the index of the first bad field."""
    module, out, precision = toy
    name = module.__name__
    harness = tmp_path / "check.c"
    harness.write_text(f"""#include <stdio.h>
#include "{name}.h"
int main(void) {{
    {name}_params p = {name.upper()}_PARAMS_DEFAULT;
    int ok = {name}_params_check(&p);
    p.a = 2;               /* field 6 */
    int a = {name}_params_check(&p);
    p.Q[1] = 3;            /* field 3, asymmetric: reported before a */
    int q = {name}_params_check(&p);
    p.Q[3] = 3;            /* symmetric now, indefinite (eigenvalues -1, 5, 1) */
    int indefinite = {name}_params_check(&p);
    p.Q[1] = p.Q[3] = 0.5; p.mu = 1;   /* mu = 1 is allowed */
    int back = {name}_params_check(&p);
    p.free[0] = -1e30f;    /* any number */
    printf("%d %d %d %d %d %d\\n", ok, a, q, indefinite, back, {name}_params_check(&p));
    return 0;
}}
""")
    exe = tmp_path / "check"
    subprocess.run(
        [
            GCC,
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            f"-I{out}",
            str(harness),
            str(out / f"{name}.c"),
            "-lm",
            "-o",
            str(exe),
        ],
        check=True,
        capture_output=True,
    )
    assert subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split() == [
        "0",
        "6",
        "3",
        "3",
        "6",
        "6",
    ]
    header = (out / f"{name}.h").read_text()
    assert "     * range: in (0, 1]\n" in header and "     * range: symmetric positive definite\n" in header
    assert re.search(r"\*   7 free \(any number\)", header)
    info = {p["name"]: p["range"] for p in module.info()["parameters"]}
    assert info == {
        "mu": "in (0, 1]",
        "w": "positive",
        "Q": "symmetric positive definite",
        "K": "positive",
        "c": "at least 0",
        "a": "in [-1, 1]",
        "free": None,
    }


# ------------------------------------------------- the specs' parameters, check and run time


def check_message(tmp_path, spec: Path, old: str, new: str) -> str:
    """The message of `robotgen check` (after FILE:LINE:COL: and the key's path) on ``spec``
    with ``old`` replaced by ``new``."""
    text = spec.read_text()
    assert old in text
    path = tmp_path / spec.name
    path.write_text(text.replace(old, new))
    with pytest.raises(UserErrors) as caught:
        load_system(str(path))
    (error,) = caught.value.errors
    return error.message.split(": ", 1)[1]


ANCHOR = "        tool: {xyz: [0, 0, 0.1], rpy: [0, pi/2, 0]}   # hand x along the tool: pitch 0 at the start\n"


@pytest.mark.parametrize(
    "setting, keyword, value",
    [
        ("forgetting: 2.0", "rmac_forgetting", 2.0),
        ("forgetting: 0.0", "rmac_forgetting", 0.0),
        ("torque_weight: -1", "rmac_torque_weight", -1.0),
        (
            "q: [40000, 40000, 40000, 40000, 40000, 40000, 1, 1, -2, 1, 1, 1]",
            "rmac_q",
            np.r_[np.full(6, 4e4), 1, 1, -2, 1, 1, 1],
        ),
    ],
)
def test_the_adaptive_controller_refuses_what_check_refuses(build_module, tmp_path, setting, keyword, value):
    module = build_module(RMAC)
    said = check_message(tmp_path, RMAC, ANCHOR, ANCHOR + f"        {setting}\n")
    refusals = []
    for fn, call in (
        ("AdaptiveController", lambda: module.AdaptiveController(**{keyword: value})),
        ("AdaptiveController.parameters", lambda: module.AdaptiveController().parameters.__setitem__(keyword, value)),
        ("AdaptiveController.parameters", lambda: setattr(module.AdaptiveController(), "parameters", {keyword: value})),
        (
            "adaptive_step",
            lambda: module.adaptive_step(
                np.zeros(6),
                np.zeros(6),
                np.eye(4),
                np.zeros(6),
                np.zeros(6),
                state=np.zeros(698),
                adapt=1.0,
                **{keyword: value},
            ),
        ),
    ):
        with pytest.raises(ValueError) as caught:
            call()
        refusals.append(str(caught.value))
        assert str(caught.value).startswith(f"{fn}(): argument '{keyword}'"), caught.value
    assert {r.split(": ", 2)[2] for r in refusals} == {said}


def test_matrix_weights_and_tree_gains_are_refused_as_check_refuses_them(tmp_path, build_module):
    """Q given as a matrix (check at the spec) and the toy's Q, which has the law's own
    bounds; the Styx hand's scalar gain at run time against check on the spec."""
    rows = "".join(
        f"          - [{', '.join(str(v) for v in row)}]\n"
        for row in np.diag(np.r_[np.full(6, 4e4), np.ones(6)]) - np.eye(12, k=1) * 3e4 - np.eye(12, k=-1) * 3e4
    )
    said = check_message(tmp_path, RMAC, ANCHOR, ANCHOR + "        q:\n" + rows)
    violation = Q_MATRIX.violation(
        np.diag(np.r_[np.full(6, 4e4), np.ones(6)]) - np.eye(12, k=1) * 3e4 - np.eye(12, k=-1) * 3e4
    )
    assert said == violation.message and said.startswith("Q must be positive definite (eq 38): its smallest eigenvalue")
    assert R_MATRIX.violation(np.eye(6)) is None
    hand = build_module(HIGH)
    said = check_message(tmp_path, HIGH, "kp: 100", "kp: -100")
    theta = hand.plant_inverse([0.0, 0.12, 0.0])
    state = hand.servo_init(theta, np.zeros(4))
    with pytest.raises(ValueError) as caught:
        hand.servo_step(
            theta,
            np.zeros(4),
            **{k: np.zeros(3) for k in ("x_e", "xd_e", "xdd_e", "f_e")},
            f_i=[1.0],
            state=state,
            dt=1e-3,
            ct_hand_kp=-100.0,
        )
    assert str(caught.value) == f"servo_step(): argument 'ct_hand_kp': {said}"


def test_the_docs_quote_the_messages_the_bounds_give():
    """docs/spec-format.md's table of ranges: each example is what the parameter's bounds say."""
    docs = (ROOT / "docs" / "spec-format.md").read_text()
    table = docs.split("## Run-time parameters")[1].split("\n## ")[0]
    quoted = re.findall(r"^\| .* \| `([^`]+)` \|$", table, re.M)
    said = [
        bounds.violation(value).message
        for bounds, value in (
            (GAIN, -2.0),
            (GAIN_MATRIX, [[1, 2, 0], [2, 1, 0], [0, 0, 1]]),
            (DAMPING, -1.0),
            (KF_INTERNAL, 1.5),
            (KI_INTERNAL, -1.0),
            (force.STIFFNESS[0], -1.0),
            (force.DAMPING[0], 0.0),
            (force.INERTIA[1], [[1, 2], [2, 1]]),
            (force.SELECTION, 1.5),
            (force.FORCE_INTEGRAL_GAIN, -1.0),
            (PAYLOAD_MASS, -1.0),
            (HAND_GAIN, -1.0),
            (WEIGHT, -2.0),
            (Q_MATRIX, [[1, 0], [0.5, 1]]),
            (TORQUE_WEIGHT, -1.0),
            (FORGETTING, 2.0),
        )
    ]
    assert quoted == said
