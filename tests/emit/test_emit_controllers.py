"""Controller classes in the emitted code (robotgen.emit.controllers): the state struct with
its reset and step functions in C, the class in the extension, the stub, info() and the
manifest. The specs' controllers are checked against CasADi's evaluation of the same
kernels (robotgen.symbolic.kernels_for), with the controller state carried by hand; a toy
controller built with make_kernel covers what the specs do not (no run-time parameters, no
init, several flags, single precision)."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from reference import hadamard_ratios

from robotgen.emit import build
from robotgen.emit import compile as emit_compile
from robotgen.emit.controllers import snake_case
from robotgen.emit.sx_program import KernelError
from robotgen.frontend import load_system
from robotgen.symbolic import controllers_for, kernels_for
from robotgen.symbolic.kernel import PARAMS, make_kernel
from robotgen.symbolic.rigid_body.inverse_jacobian import SINGULAR_DETERMINANT
from robotgen.symbolic.root_laws.hand import Hand
from robotgen.symbolic.root_laws.law import Controller, StateView

ROOT = Path(__file__).resolve().parents[2]
RMAC_SPEC = ROOT / "specs" / "puma560_rmac.yaml"
GCC, CLANG = shutil.which("gcc"), shutil.which("clang")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
STEPS = 20
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is required")

# a static object (not const) in C; a static function (code, like rg_sincos2) is not state
MUTABLE_STATIC = r"\bstatic\b(?!\s+const\b)(?![^;={(]*\()"


# ------------------------------------------------------------------------------ helpers


def load_module(directory: Path, name: str):
    path = directory / (name + emit_compile.extension_suffix())
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# The emitted C multiplies by shared reciprocals where CasADi's evaluator divides
# (robotgen.emit.sx_program), so the two differ in the last bits; the adaptive step's solves
# and its RLS update, carried from period to period, amplify that to ~1e-10 of the torques
# after a few periods (a wrong term would differ in the leading digits).
DOUBLE_RTOL = 1e-8


def assert_close(actual, expected, rtol=DOUBLE_RTOL):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    assert actual.shape == expected.shape
    scale = np.abs(expected).max(initial=1.0)
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * scale)


class Chain:
    """A controller's kernels evaluated by CasADi, its state carried by hand: init on the
    first step (or a zero state without init), then step after step."""

    def __init__(self, kernels: dict, controller: Controller, **parameters):
        self.controller = controller
        self.step_kernel = kernels[controller.step]
        self.init_kernel = kernels[controller.init] if controller.init else None
        self.parameters = parameters
        self.flags = dict.fromkeys(controller.flags, True)
        self.state = None

    def _params(self, kernel) -> list:
        port = kernel.inputs[-1]
        if port.name != PARAMS:
            return []
        return [
            np.concatenate(
                [np.ravel(np.asarray(self.parameters.get(p.name, p.default), float)) for p in port.parameters]
            )
        ]

    def step(self, q, qd, pose_d, twist_d, accel_d) -> tuple[np.ndarray, dict]:
        args = [q, qd, np.ravel(pose_d), twist_d, accel_d]
        n = self.controller.state_size
        if self.state is None:
            if self.init_kernel is not None:
                self.state = np.array(self.init_kernel.function(*args, *self._params(self.init_kernel))).ravel()
            else:
                self.state = np.zeros(n)
        state = [self.state] if n else []
        flags = [1.0 if self.flags[f] else 0.0 for f in self.controller.flags]
        result = self.step_kernel.function(*args, *state, *flags, *self._params(self.step_kernel))
        result = result if isinstance(result, (list, tuple)) else [result]
        outputs = {
            p.name: np.array(v, float).ravel().reshape((p.rows, p.cols) if p.is_matrix else (p.rows,))
            for v, p in zip(result, self.step_kernel.outputs)
        }
        if n:
            self.state = outputs.pop("state_next")
        tau = outputs.pop(self.step_kernel.outputs[0].name)
        return tau, outputs

    def view(self, name: str) -> np.ndarray:
        v = next(v for v in self.controller.views if v.name == name)
        block = self.state[v.offset : v.offset + v.rows * v.cols]
        return block.reshape(v.rows, v.cols) if v.cols > 1 else block


def hand_trajectory(system, steps: int, period: float) -> list[tuple]:
    """A smooth desired hand trajectory (the pose, twist and acceleration of the hand along a
    sinusoidal joint motion) and a measured joint state near it, one tuple per period."""
    node = system.root_node
    hand = Hand(system.nodes[node.robot].leaf, node.hand.tool)
    q, qd, qdd = ca.SX.sym("q", 6), ca.SX.sym("qd", 6), ca.SX.sym("qdd", 6)
    R, p = hand.pose(q)
    J = hand.jacobian(q)
    f = ca.Function(
        "f", [q, qd, qdd], [ca.vertcat(ca.horzcat(R, p), ca.DM([[0, 0, 0, 1]])), J @ qd, J @ qdd + hand.bias(q, qd)]
    )
    q0 = np.array([0.1, 0.6, -0.4, 0.3, 0.5, 0.2])
    a, w = np.array([0.2, -0.1, 0.15, 0.3, -0.2, 0.25]), 2.0
    out = []
    for k in range(steps):
        t = k * period
        q_d, qd_d, qdd_d = q0 + a * np.sin(w * t), a * w * np.cos(w * t), -a * w * w * np.sin(w * t)
        pose, twist, accel = (np.array(v, float) for v in f(q_d, qd_d, qdd_d))
        q_m = q_d + 0.01 * np.array([1, -1, 1, -1, 1, -1]) * np.cos(3 * t)
        qd_m = qd_d + 0.02 * np.sin(5 * t + np.arange(6))
        out.append((q_m, qd_m, pose, twist.ravel(), accel.ravel()))
    return out


def rac_spec_text() -> str:
    text = RMAC_SPEC.read_text()
    assert text.count("resolved_adaptive") == 2 and text.count("name: puma560_rmac") == 1
    return text.replace("resolved_adaptive", "resolved_acceleration").replace("name: puma560_rmac", "name: puma560_rac")


class Built:
    def __init__(self, spec: Path, build_module):
        """The spec built once per test session (conftest's build_module), so that every
        test file sees the same module under its name."""
        self.system = load_system(str(spec))
        self.name = self.system.name
        self.module = build_module(spec)
        self.dir = Path(self.module.__file__).parent
        self.kernels = {k.name: k for k in kernels_for(self.system)}
        (self.controller,) = controllers_for(self.system)
        self.cls = getattr(self.module, self.controller.class_name)
        self.trajectory = hand_trajectory(self.system, STEPS, self.controller.period)

    def chain(self, **parameters) -> Chain:
        return Chain(self.kernels, self.controller, **parameters)


@pytest.fixture(scope="module")
def rmac(build_module) -> Built:
    return Built(RMAC_SPEC, build_module)


@pytest.fixture(scope="session")
def rac_spec_path(tmp_path_factory) -> Path:
    spec = tmp_path_factory.mktemp("rac_spec") / "puma560_rac.yaml"
    spec.write_text(rac_spec_text())
    return spec


@pytest.fixture(scope="module")
def rac(build_module, rac_spec_path) -> Built:
    return Built(rac_spec_path, build_module)


# ------------------------------------------------------------------ the adaptive controller


def test_adaptive_controller_follows_the_casadi_kernel_chain(rmac):
    controller, chain = rmac.cls(), rmac.chain()
    assert controller.last == {} and not controller.state.any()
    for k, point in enumerate(rmac.trajectory):
        tau, others = chain.step(*point)
        assert_close(controller.step(*point), tau)
        assert sorted(controller.last) == ["dx"]
        assert_close(controller.last["dx"], others["dx"])
        assert_close(controller.state, chain.state)
        for name, shape in (("A", (12, 12)), ("B", (12, 6)), ("c", (12,)), ("P", (19, 19))):
            view = getattr(controller, name)
            assert view.shape == shape and view.dtype == np.float64
            assert_close(view, chain.view(name))
        if k == 0:
            first = tau
    assert not np.allclose(tau, first)  # the trajectory moves


def test_adaptive_controller_identifies_when_adapting(rmac):
    init = rmac.kernels["adaptive_init"]
    q, qd, pose, twist, accel = rmac.trajectory[0]
    A0 = np.array(init.function(q, qd, pose.ravel(), twist, accel)).ravel()[:144].reshape(12, 12)
    controller = rmac.cls()
    for point in rmac.trajectory:
        controller.step(*point)
    assert controller.adapt is True
    assert np.abs(controller.A - A0).max() > 1e-9  # RLS moved A


def test_adapt_false_keeps_the_model_from_init(rmac):
    controller, chain = rmac.cls(), rmac.chain()
    assert controller.adapt is True
    controller.adapt = False
    chain.flags["adapt"] = False
    for k, point in enumerate(rmac.trajectory):
        tau, _ = chain.step(*point)
        assert_close(controller.step(*point), tau)
        if k == 0:
            A, B, P = controller.A, controller.B, controller.P
            init = rmac.kernels["adaptive_init"]
            start = np.array(init.function(point[0], point[1], point[2].ravel(), point[3], point[4])).ravel()
            assert_close(A, start[:144].reshape(12, 12))  # the C of adaptive_init vs CasADi's evaluation
            assert_close(B, start[144:216].reshape(12, 6))
            np.testing.assert_array_equal(P, start[228:589].reshape(19, 19))
    np.testing.assert_array_equal(controller.A, A)
    np.testing.assert_array_equal(controller.B, B)
    np.testing.assert_array_equal(controller.P, P)
    assert controller.adapt is False
    controller.adapt = np.bool_(True)
    assert controller.adapt is True
    controller.adapt = 0
    assert controller.adapt is False


def test_reset_restarts(rmac):
    fresh = rmac.cls().step(*rmac.trajectory[3])
    controller = rmac.cls()
    for point in rmac.trajectory[:6]:
        controller.step(*point)
    controller.adapt = False
    assert controller.reset() is None
    assert controller.adapt is True and controller.last == {} and not controller.state.any()
    assert not controller.A.any()
    np.testing.assert_array_equal(controller.step(*rmac.trajectory[3]), fresh)


def test_parameters_change_the_result_as_casadi_predicts(rmac):
    changed = {"rmac_forgetting": 0.9, "rmac_torque_weight": 2.5}
    controller, chain = rmac.cls(**changed), rmac.chain(**changed)
    default = rmac.cls()
    assert controller.parameters["rmac_forgetting"] == 0.9
    assert controller.parameters["rmac_torque_weight"] == 2.5
    q_weights = np.linspace(1e5, 2e6, 12)
    for k, point in enumerate(rmac.trajectory):
        if k == 5:  # per key, from the next step on
            controller.parameters["rmac_q"] = q_weights
            chain.parameters["rmac_q"] = q_weights
        if k == 10:  # as a whole: names left out take the spec's value
            controller.parameters = {"rmac_forgetting": 0.95}
            chain.parameters = {"rmac_forgetting": 0.95}
        tau, others = chain.step(*point)
        assert_close(controller.step(*point), tau)
        assert_close(controller.last["dx"], others["dx"])
        assert_close(controller.P, chain.view("P"))
        default_tau = default.step(*point)
    assert not np.allclose(default_tau, tau, rtol=1e-9, atol=0)
    parameters = controller.parameters
    assert sorted(parameters) == ["rmac_forgetting", "rmac_q", "rmac_torque_weight"] and len(parameters) == 3
    assert parameters["rmac_forgetting"] == 0.95 and "rmac_q" in parameters and "x" not in parameters
    np.testing.assert_array_equal(parameters["rmac_q"], rmac.module.parameters["rmac_q"])
    assert dict(parameters.items()).keys() == set(parameters.keys())
    assert parameters.get("nope", 7) == 7
    # the defaults of the module and its functions are untouched
    assert default.parameters["rmac_torque_weight"] == rmac.module.parameters["rmac_torque_weight"]
    # one controller's parameters copied to another
    other = rmac.cls()
    other.parameters = controller.parameters
    assert repr(other.parameters) == repr(controller.parameters)
    # reset keeps them
    controller.reset()
    assert controller.parameters["rmac_forgetting"] == 0.95


def test_period(rmac, rac):
    for built in (rmac, rac):
        controller = built.cls()
        assert controller.period == 0.001 == built.controller.period
        assert isinstance(controller.period, float)
        with pytest.raises(AttributeError):
            controller.period = 0.002
        macro = snake_case(built.controller.class_name)
        header = (built.dir / f"{built.name}.h").read_text()
        assert f"#define {built.name.upper()}_{macro.upper()}_CONTROLLER_PERIOD 0.001 /* seconds */" in header


# -------------------------------------------------------- the resolved acceleration controller


def test_resolved_acceleration_controller_equals_its_kernel(rac):
    controller, chain = rac.cls(), rac.chain()
    assert controller.state.shape == (0,) and controller.last == {}
    assert not hasattr(controller, "adapt")
    for point in rac.trajectory:
        tau, others = chain.step(*point)
        assert_close(controller.step(*point), tau)
        assert sorted(controller.last) == ["error"]
        assert_close(controller.last["error"], others["error"])
        # a stateless controller is the module function
        assert_close(controller.step(*point), rac.module.resolved_acceleration_step(*point)[0])
    gains = {"rmac_kp": np.full(6, 100.0), "rmac_kv": np.linspace(10, 30, 6)}
    controller, chain = rac.cls(**gains), rac.chain(**gains)
    for point in rac.trajectory[:5]:
        tau, _ = chain.step(*point)
        assert_close(controller.step(*point), tau)
        assert_close(tau, rac.module.resolved_acceleration_step(*point, **gains)[0])


def test_keyword_arguments_of_step(rac):
    q, qd, pose, twist, accel = rac.trajectory[2]
    controller = rac.cls()
    expected = controller.step(q, qd, pose, twist, accel)
    assert_close(controller.step(q, qd, accel_d=accel, twist_d=twist, pose_d=pose.tolist()), expected)


def test_step_writes_into_out(rac, rmac):
    """out= takes tau's array: the same torques, the same object back, checked like a function's."""
    for built in (rac, rmac):
        fresh, into = built.cls(), built.cls()
        tau = np.full(6, np.nan)
        for point in built.trajectory[:4]:
            expected = fresh.step(*point)
            assert into.step(*point, out=tau) is tau
            np.testing.assert_array_equal(tau, expected)
        assert into.step(*built.trajectory[0], out=None) is not tau
    controller, point = rac.cls(), rac.trajectory[0]
    with pytest.raises(ValueError, match=r"step\(\): out for 'tau' must have shape \(6,\), got \(7,\)"):
        controller.step(*point, out=np.empty(7))
    with pytest.raises(ValueError, match=r"out for 'tau' shares memory with the argument 'q'"):
        controller.step(*point, out=point[0])
    with pytest.raises(TypeError, match=r"out must be a float64 numpy array for 'tau', got list"):
        controller.step(*point, out=[0.0] * 6)


def test_step_in_a_loop_fills_the_torques_it_was_let_go_of(rac, rmac):
    """tau = controller.step(...) in a loop: the same torques as a twin writing into out=, in
    two arrays taken in turn once the first two steps have made them."""
    for built in (rac, rmac):
        looped, twin = built.cls(), built.cls()
        expected, seen, tau = np.empty(6), set(), None
        for point in built.trajectory[:5]:
            tau = looped.step(*point)
            twin.step(*point, out=expected)
            np.testing.assert_array_equal(tau, expected)
            seen.add(id(tau))
        assert len(seen) == 2


def _wrist(q5: float) -> np.ndarray:
    """A PUMA posture; q5 = 0 aligns joints 4 and 6 (the wrist singularity)."""
    return np.array([0.1, -0.5, 0.4, 0.2, q5, 0.3])


def test_a_singular_hand_jacobian_is_status_2_not_huge_torques(rac):
    """J^-1 at the wrist singularity does not exist, and near it the solve amplifies the command
    without bound: the PUMA's step (two 3 x 3 solves at the wrist centre) refuses (status 2,
    zero outputs) when a block of the same J taken at the wrist centre, in numpy, has |det|
    below SINGULAR_DETERMINANT of the product of its column norms, and answers otherwise."""
    node = rac.system.root_node
    hand = Hand(rac.system.nodes[node.robot].leaf, node.hand.tool)
    assert hand.wrist_centre is not None
    J = ca.Function("J", [q := ca.SX.sym("q", 6)], [hand.jacobian(q)])
    tripped = []
    for q5 in [0.0, *np.geomspace(1e-10, 1e-2, 41), -1e-9, 0.5]:
        # the hand held where it is (a controller's first step refuses a pose_d far from it) and moved
        rest = (np.zeros(6), rac.module.hand_pose(_wrist(q5)), np.zeros(6), np.array([0.1, 0, 0, 0, 0, 0.1]))
        ratio = min(hadamard_ratios(np.array(J(_wrist(q5)))))
        if abs(ratio / SINGULAR_DETERMINANT - 1) < 0.01:
            continue  # rounding decides at the threshold itself
        if ratio < SINGULAR_DETERMINANT:
            tripped.append(q5)
            for call in (rac.module.resolved_acceleration_step, rac.cls().step):
                with pytest.raises(FloatingPointError, match="status 2"):
                    call(_wrist(q5), *rest)
        else:
            tau, _ = rac.module.resolved_acceleration_step(_wrist(q5), *rest)
            assert np.all(np.isfinite(tau))
    assert 0.0 in tripped and -1e-9 in tripped and 0.5 not in tripped and max(tripped) < 1.01e-6


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_nan_or_infinite_measurement_is_status_1(rac, rmac, bad):
    q, qd, pose, twist, accel = rac.trajectory[1]
    for module, step in ((rac.module, "resolved_acceleration_step"), (rmac.module, "adaptive_init")):
        with pytest.raises(FloatingPointError, match="status 1"):
            getattr(module, step)(np.where(np.arange(6) == 2, bad, q), qd, pose, twist, accel)
    controller = rmac.cls()
    controller.step(q, qd, pose, twist, accel)
    state = controller.state.copy()
    with pytest.raises(FloatingPointError, match="status 1"):
        controller.step(q, np.where(np.arange(6) == 4, bad, qd), pose, twist, accel)
    assert np.array_equal(controller.state, state)  # nothing written: the next step starts from here


# ------------------------------------------------------------------------------ errors

POINT = (np.zeros(6), np.zeros(6), np.eye(4), np.zeros(6), np.zeros(6))


@pytest.mark.parametrize(
    "call, kind, message",
    [
        (
            lambda c: c.step(np.zeros(5), *POINT[1:]),
            ValueError,
            "AdaptiveController.step(): argument 'q' must have shape (6,) (one point, no batch axis), got (5,)",
        ),
        (
            lambda c: c.step(POINT[0], POINT[1], np.zeros(16), *POINT[3:]),
            ValueError,
            "argument 'pose_d' must have shape (4, 4) (one point, no batch axis), got (16,)",
        ),
        (lambda c: c.step(np.zeros((2, 6)), *POINT[1:]), ValueError, "argument 'q' must have shape (6,)"),
        (
            lambda c: c.step(POINT[0], None, *POINT[2:]),
            TypeError,
            "AdaptiveController.step(): argument 'qd' must be a float64 array of shape (6,), got None",
        ),
        (
            lambda c: c.step(*POINT[:4], "abc"),
            TypeError,
            "argument 'accel_d' must be a float64 array of shape (6,), got str",
        ),
        (
            lambda c: c.step(*POINT[:4], ["x"] * 6),
            ValueError,
            "argument 'accel_d' must be a float64 array of shape (6,)",
        ),
        (
            lambda c: c.step(*POINT[:4]),
            TypeError,
            "AdaptiveController.step() missing 1 required positional argument: 'accel_d'",
        ),
        (lambda c: c.step(*POINT, POINT[0]), TypeError, "takes 5 positional arguments but 6 were given"),
        (lambda c: c.step(*POINT, rmac_forgetting=0.9), TypeError, "unexpected keyword argument 'rmac_forgetting'"),
        (lambda c: type(c)(0.9), TypeError, "AdaptiveController() takes no positional arguments"),
        (
            lambda c: type(c)(forgetting=0.9),
            TypeError,
            "AdaptiveController() got an unexpected keyword argument 'forgetting' (its run-time parameters are rmac_q, "
            "rmac_torque_weight, rmac_forgetting)",
        ),
        (lambda c: type(c)(rmac_q=np.ones(5)), ValueError, "argument 'rmac_q' must have shape (12,), got (5,)"),
        (lambda c: type(c)(rmac_forgetting=None), TypeError, "argument 'rmac_forgetting' must be a number"),
        (
            lambda c: c.parameters.__setitem__("rmac_q", np.ones(3)),
            ValueError,
            "AdaptiveController.parameters(): argument 'rmac_q' must have shape (12,), got (3,)",
        ),
        (lambda c: c.parameters.__setitem__("rmac_s", 1.0), KeyError, "'rmac_s' is not a run-time parameter"),
        (lambda c: c.parameters.__delitem__("rmac_q"), TypeError, "cannot be deleted"),
        (lambda c: c.parameters["nope"], KeyError, "nope"),
        (lambda c: setattr(c, "parameters", [1.0]), TypeError, "AdaptiveController.parameters must be a mapping"),
        (lambda c: setattr(c, "parameters", {"rmac_q": "x"}), TypeError, "argument 'rmac_q' must be"),
        (lambda c: delattr(c, "parameters"), AttributeError, "cannot delete"),
        (lambda c: setattr(c, "adapt", "no"), TypeError, "AdaptiveController.adapt must be a bool, got str"),
        (lambda c: delattr(c, "adapt"), AttributeError, "cannot delete"),
        (lambda c: setattr(c, "A", np.eye(12)), AttributeError, "not writable"),
        (lambda c: setattr(c, "state", np.zeros(698)), AttributeError, "not writable"),
        (lambda c: setattr(c, "x", 1), AttributeError, "x"),
    ],
)
def test_errors_are_clear(rmac, call, kind, message):
    controller = rmac.cls()
    with pytest.raises(kind) as error:
        call(controller)
    assert message in str(error.value)


def test_a_failed_change_leaves_the_parameters_as_they_were(rmac):
    controller = rmac.cls(rmac_forgetting=0.9)
    with pytest.raises(ValueError):
        controller.parameters = {"rmac_forgetting": 0.5, "rmac_q": np.ones(2)}
    assert controller.parameters["rmac_forgetting"] == 0.9
    with pytest.raises(ValueError):
        controller.parameters["rmac_q"] = np.ones(13)
    np.testing.assert_array_equal(controller.parameters["rmac_q"], rmac.module.parameters["rmac_q"])


def test_errors_leak_no_references(rmac):
    controller = rmac.cls()
    point = [np.array(v) for v in rmac.trajectory[0]]
    controller.step(*point)
    before = [sys.getrefcount(v) for v in point]
    for _ in range(100):
        with pytest.raises(ValueError):
            controller.step(point[0], point[1], point[2].ravel(), point[3], point[4])
        controller.step(*point)
        controller.parameters["rmac_q"] = controller.parameters["rmac_q"]
        _ = controller.A, controller.last, controller.state, dict(controller.parameters)
    assert [sys.getrefcount(v) for v in point] == before


# ------------------------------------------------------------- documentation, stub, manifest


def test_docs_info_and_manifest(rmac, rac):
    import inspect
    import json

    signature = inspect.signature(rmac.cls)
    assert list(signature.parameters) == ["rmac_q", "rmac_torque_weight", "rmac_forgetting"]
    assert all(p.kind is p.KEYWORD_ONLY for p in signature.parameters.values())
    assert signature.parameters["rmac_forgetting"].default == 0.99
    assert list(inspect.signature(rmac.cls().step).parameters) == ["q", "qd", "pose_d", "twist_d", "accel_d", "out"]
    assert "Resolved motion adaptive control" in rmac.cls.__doc__
    assert "Resolved motion adaptive control" in rmac.cls.step.__doc__
    assert "eq 29" in rmac.cls.A.__doc__
    expected = {
        "class": "AdaptiveController",
        "c_type": "puma560_rmac_adaptive_controller",
        "step": "adaptive_step",
        "init": "adaptive_init",
        "period": 0.001,
        "state_size": 698,
        "flags": ["adapt"],
        "outputs": ["dx"],
        "reads_parameters": True,
        "start_check": {"function": "hand_distance", "limits": [0.01, 0.05], "units": ["m", "rad"]},
        "views": [
            {"name": "A", "offset": 0, "shape": [12, 12]},
            {"name": "B", "offset": 144, "shape": [12, 6]},
            {"name": "c", "offset": 216, "shape": [12]},
            {"name": "P", "offset": 228, "shape": [19, 19]},
        ],
    }
    (info,) = rmac.module.info()["controllers"]
    for view in info["views"]:
        assert view.pop("doc")
    assert info == expected
    manifest = json.loads((rmac.dir / "manifest.json").read_text())
    assert [c["class"] for c in manifest["controllers"]] == ["AdaptiveController"]
    (info,) = rac.module.info()["controllers"]
    assert info == {
        "class": "ResolvedAccelerationController",
        "c_type": "puma560_rac_resolved_acceleration_controller",
        "step": "resolved_acceleration_step",
        "init": None,
        "period": 0.001,
        "state_size": 0,
        "flags": [],
        "outputs": ["error"],
        "reads_parameters": True,
        "views": [],
        "start_check": expected["start_check"],
    }
    assert "AdaptiveController" in rmac.module.__doc__ and "controllers" in rmac.module.info.__doc__


def test_header_declares_the_struct_and_functions(rmac, rac):
    header = (rmac.dir / "puma560_rmac.h").read_text()
    assert (
        "typedef struct {\n    double state[PUMA560_RMAC_ADAPTIVE_CONTROLLER_STATE_SIZE];\n    double dx[12];\n"
        "    int initialised;\n    int adapt;\n} puma560_rmac_adaptive_controller;"
    ) in header
    assert "#define PUMA560_RMAC_ADAPTIVE_CONTROLLER_STATE_SIZE 698" in header
    assert "#define PUMA560_RMAC_ADAPTIVE_CONTROLLER_P_OFFSET 228" in header
    assert "[228, 589) P (19, 19) row-major: the RLS covariance P (eq 37)" in header
    comments = re.sub(r"\n \*\s*", " ", header)  # comment lines joined
    assert "The caller owns the struct: one per controlled arm, stepped from one thread" in comments
    assert "a struct is not for sharing between threads" in comments
    assert "void puma560_rmac_adaptive_controller_reset(puma560_rmac_adaptive_controller *controller);" in header
    assert (
        "int puma560_rmac_adaptive_controller_step(puma560_rmac_adaptive_controller *controller, const double *q, "
        "const double *qd, const double *pose_d, const double *twist_d, const double *accel_d, "
        "const puma560_rmac_params *params, double *tau);"
    ) in header
    header = (rac.dir / "puma560_rac.h").read_text()
    assert (
        "typedef struct {\n    double error[6];\n    int initialised;\n} puma560_rac_resolved_acceleration_controller;"
    ) in header


def test_no_mutable_state_beyond_what_cpython_needs(rmac):
    for file in ("puma560_rmac.c", "puma560_rmac.h"):
        text = (rmac.dir / file).read_text()
        assert not re.search(MUTABLE_STATIC, text)
        assert not re.search(r"\b(malloc|calloc|realloc|free|printf|fopen)\s*\(", text)
    found = set(
        re.findall(
            r"^static (?!const\b)[^(=;]*?\**(\w+)(?:\[[^]]*\])?\s*(?:=|;)",
            (rmac.dir / "puma560_rmac_module.c").read_text(),
            re.M,
        )
    )
    # each function's spare results (handed out again once let go of: test_emit.py)
    spares = {f"k_{name}_spare" for name in rmac.module.info()["functions"]}
    assert spares <= found
    # the keyword names made at import, and CPython's type, method and module tables
    assert found - spares == {
        "rg_keys",
        "rg_methods",
        "rg_module",
        "rg_parameters_type",
        "rg_parameters_mapping",
        "rg_parameters_sequence",
        "rg_parameters_methods",
        "rgc_AdaptiveController_methods",
        "rgc_AdaptiveController_getset",
        "rgc_AdaptiveController_type",
    }


def test_stub_declares_the_classes(rmac):
    stub = (rmac.dir / "puma560_rmac.pyi").read_text()
    assert "@final\nclass AdaptiveController:" in stub
    assert (
        "    def __init__(self, *, rmac_q: npt.ArrayLike = ..., rmac_torque_weight: float = ..., "
        "rmac_forgetting: float = ...) -> None: ..."
    ) in stub
    assert "    adapt: bool\n" in stub and "    def P(self) -> npt.NDArray[np.float64]:" in stub


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy not installed")
def test_mypy_and_stubtest(rmac, tmp_path):
    (tmp_path / "good.py").write_text(
        "import numpy as np\nimport puma560_rmac as m\n\n"
        "c = m.AdaptiveController(rmac_forgetting=0.95, rmac_q=np.ones(12))\n"
        "tau = c.step(np.zeros(6), np.zeros(6), np.eye(4), np.zeros(6), np.zeros(6))\n"
        "c.adapt = False\n"
        "c.parameters['rmac_forgetting'] = 0.9\n"
        "c.parameters = {'rmac_forgetting': 0.9}\n"
        "period: float = c.period\n"
        "A = c.A + c.B.sum() + c.P.trace() + c.state.sum() + c.last['dx'].sum()\n"
        "c.reset()\n"
        "print(tau.shape, A.shape, period, dict(c.parameters), list(c.parameters))\n"
    )
    (tmp_path / "bad.py").write_text(
        "import numpy as np\nimport puma560_rmac as m\n\n"
        "c = m.AdaptiveController(rmac_forgeting=0.95)\n"
        "c.step(np.zeros(6))\n"
        "c.period = 0.002\n"
        "c.A = np.eye(12)\n"
    )
    env = {**os.environ, "MYPYPATH": str(rmac.dir)}
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--cache-dir", os.devnull, "good.py", "bad.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert not [e for e in errors if e.startswith("good.py")], result.stdout
    assert 'bad.py:4: error: Unexpected keyword argument "rmac_forgeting"' in result.stdout
    assert "bad.py:5: error: Missing positional arguments" in result.stdout
    assert 'bad.py:6: error: Property "period" defined in "AdaptiveController" is read-only' in result.stdout
    assert 'bad.py:7: error: Property "A" defined in "AdaptiveController" is read-only' in result.stdout
    env["PYTHONPATH"] = str(rmac.dir)
    result = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "puma560_rmac"], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


# ------------------------------------------------------------------------------------ C


def c_program(built: Built, points: list[tuple]) -> str:
    """Resets a controller struct and steps it through ``points``, printing tau (and the
    other outputs kept in the struct) after each step."""
    name, c = built.name, built.controller
    prefix = f"{name}_{snake_case(c.class_name)}_controller"
    rows = [", ".join(repr(float(v)) for part in point for v in np.ravel(part)) for point in points]
    outputs = [p for p in built.kernels[c.step].outputs[1:] if p.name != "state_next"]
    lines = [
        "#include <stdio.h>",
        f'#include "{name}.h"',
        "",
        f"static const double points[{len(points)}][40] = {{",
        *(f"    {{{row}}}," for row in rows),
        "};",
        "",
        "int main(void)",
        "{",
        f"    {prefix} controller;",
        f"    {name}_params params = {name.upper()}_PARAMS_DEFAULT;",
        "    double tau[6];",
        "    int k, i;",
        f"    {prefix}_reset(&controller);",
        f"    for (k = 0; k < {len(points)}; ++k) {{",
        "        const double *x = points[k];",
        f"        if ({prefix}_step(&controller, x, x + 6, x + 12, x + 28, x + 34, &params, tau) != 0) {{",
        "            return 1;",
        "        }",
        "        for (i = 0; i < 6; ++i) {",
        '            printf("%.17g\\n", tau[i]);',
        "        }",
    ]
    for p in outputs:
        lines += [
            f"        for (i = 0; i < {p.size}; ++i) {{",
            f'            printf("%.17g\\n", controller.{p.name}[i]);',
            "        }",
        ]
    lines += ["    }", "    return 0;", "}", ""]
    return "\n".join(lines)


@pytest.fixture(scope="module")
def c_objects(rmac, rac, tmp_path_factory):
    """Each module's C source compiled by gcc and clang with the strict flags (in parallel)."""
    out = tmp_path_factory.mktemp("objects")
    jobs = {}
    for built in (rmac, rac):
        for compiler in (GCC, CLANG):
            if compiler is None:
                continue
            target = out / f"{built.name}-{Path(compiler).name}.o"
            jobs[built.name, compiler] = (
                target,
                subprocess.Popen(
                    [compiler, *STRICT, "-O2", "-c", str(built.dir / f"{built.name}.c"), "-o", str(target)],
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    text=True,
                ),
            )
    objects = {}
    for key, (target, job) in jobs.items():
        output, _ = job.communicate()
        assert job.returncode == 0, output
        objects[key] = target
    return objects


@pytest.mark.parametrize("which", ["rmac", "rac"])
@pytest.mark.parametrize("compiler", [GCC, CLANG], ids=["gcc", "clang"])
def test_c_program_agrees_with_python(request, c_objects, tmp_path, which, compiler):
    if compiler is None:
        pytest.skip("clang not installed")
    built = request.getfixturevalue(which)
    (tmp_path / "main.c").write_text(c_program(built, built.trajectory))
    exe = tmp_path / "main"
    subprocess.run(
        [
            compiler,
            *STRICT,
            "-O2",
            f"-I{built.dir}",
            str(tmp_path / "main.c"),
            str(c_objects[built.name, compiler]),
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
    controller, expected = built.cls(), []
    for point in built.trajectory:
        expected.append(controller.step(*point))
        expected += [np.ravel(v) for v in controller.last.values()]
    expected = np.concatenate(expected)
    assert printed.shape == expected.shape
    assert_close(printed, expected)


# ------------------------------------------------------------------- a toy controller


def toy_kernels():
    """A stateful step without init and without run-time parameters, two flags, a 2-joint
    arm: tau = (1 + boost) (pose_d[0, 3] - q + K qd) + state[0]; the state's K (2x2 at 1)
    integrates q unless hold."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    pose_d, twist_d, accel_d = ca.SX.sym("pose_d", 16), ca.SX.sym("twist_d", 6), ca.SX.sym("accel_d", 6)
    state, hold, boost = ca.SX.sym("state", 6), ca.SX.sym("hold"), ca.SX.sym("boost")
    K = ca.reshape(state[1:5], 2, 2).T
    tau = (1 + boost) * (pose_d[3] - q + K @ qd) + state[0] + ca.sin(twist_d[:2]) * accel_d[:2]
    grown = ca.vertcat(state[0] + 0.5, state[1:5] + ca.vertcat(q, qd), state[5] - 1)
    step = make_kernel(
        "toy_step",
        "A toy step: tau from q, the state's K and two flags.",
        [
            ("q", q),
            ("qd", qd),
            ("pose_d", pose_d, (4, 4)),
            ("twist_d", twist_d),
            ("accel_d", accel_d),
            ("state", state),
            ("hold", hold),
            ("boost", boost),
        ],
        [("tau", tau, (2, 1)), ("gap", pose_d[3] - q, (2, 1)), ("state_next", ca.if_else(hold, state, grown), (6, 1))],
    )
    return [step]


TOY = Controller(
    "ToyController",
    "toy_step",
    0.0025,
    6,
    None,
    ("hold", "boost"),
    (StateView("K", 1, 2, 2, "a toy gain"), StateView("count", 5, 1, 1, "minus the steps taken")),
)


@pytest.mark.parametrize("precision", ["double", "float"])
def test_toy_controller(tmp_path, precision):
    kernels = toy_kernels()
    out = build.emit(tmp_path / "toy", "toy", kernels, nq=2, precision=precision, controllers=[TOY])
    module = load_module(out, "toy")
    controller = module.ToyController()
    assert not hasattr(controller, "parameters") and controller.period == 0.0025
    assert controller.hold is True and controller.boost is True
    controller.hold = False
    chain = Chain({k.name: k for k in kernels}, TOY)
    chain.flags["hold"] = False
    rng = np.random.default_rng(3)
    rtol = 1e-12 if precision == "double" else 1e-5
    for k in range(6):
        point = (
            rng.normal(size=2),
            rng.normal(size=2),
            rng.normal(size=(4, 4)),
            rng.normal(size=6),
            rng.normal(size=6),
        )
        if k == 3:
            controller.boost = False
            chain.flags["boost"] = False
        tau, others = chain.step(*point)
        assert_close(controller.step(*point), tau, rtol)
        assert_close(controller.last["gap"], others["gap"], rtol)
        assert_close(controller.K, chain.view("K"), rtol)
        assert controller.count.shape == (1,)
    assert controller.count[0] == -6
    with pytest.raises(TypeError, match=r"ToyController\(\) takes no arguments"):
        module.ToyController(x=1)
    header = (out / "toy.h").read_text()
    real = "double" if precision == "double" else "float"
    assert (
        f"typedef struct {{\n    {real} state[TOY_TOY_CONTROLLER_STATE_SIZE];\n    {real} gap[2];\n"
        "    int initialised;\n    int hold;\n    int boost;\n} toy_toy_controller;"
    ) in header
    assert (
        f"int toy_toy_controller_step(toy_toy_controller *controller, const {real} *q, const {real} *qd, "
        f"const {real} *pose_d, const {real} *twist_d, const {real} *accel_d, {real} *tau);"
    ) in header
    (tmp_path / "main.c").write_text(
        f'#include <stdio.h>\n#include "toy.h"\n\nint main(void)\n{{\n    toy_toy_controller c;\n'
        f"    const {real} q[2] = {{1, 2}}, pose[16] = {{0}}, six[6] = {{0}};\n    {real} tau[2];\n"
        "    toy_toy_controller_reset(&c);\n    c.hold = 0;\n"
        "    if (toy_toy_controller_step(&c, q, q, pose, six, six, tau) != 0\n"
        "        || toy_toy_controller_step(&c, q, q, pose, six, six, tau) != 0) {\n        return 1;\n    }\n"
        '    printf("%g %g %g\\n", (double)tau[0], (double)tau[1], (double)c.state[TOY_TOY_CONTROLLER_K_OFFSET]);\n'
        "    return 0;\n}\n"
    )
    for compiler in filter(None, (GCC, CLANG)):
        subprocess.run(
            [
                compiler,
                *STRICT,
                "-O2",
                f"-I{out}",
                str(tmp_path / "main.c"),
                str(out / "toy.c"),
                "-o",
                str(tmp_path / "main"),
                "-lm",
            ],
            check=True,
            capture_output=True,
            text=True,
        )
        printed = subprocess.run([str(tmp_path / "main")], check=True, capture_output=True, text=True).stdout
        c = module.ToyController()
        c.hold = False
        c.step([1, 2], [1, 2], np.zeros((4, 4)), np.zeros(6), np.zeros(6))
        tau = c.step([1, 2], [1, 2], np.zeros((4, 4)), np.zeros(6), np.zeros(6))
        assert [float(v) for v in printed.split()] == pytest.approx([*tau, c.K[0, 0]], rel=1e-5)


def test_no_controllers_emits_as_before(tmp_path):
    kernels = toy_kernels()
    without = build.emit(tmp_path / "without", "toy", kernels, nq=2, compile=False)
    empty = build.emit(tmp_path / "empty", "toy", kernels, nq=2, compile=False, controllers=[])
    files = sorted(p.name for p in without.iterdir())
    assert files == sorted(p.name for p in empty.iterdir())
    for file in files:
        text = (without / file).read_text()
        assert text == (empty / file).read_text()
        assert "ontroller" not in text, file
    built = build.emit(tmp_path / "with", "toy", kernels, nq=2, compile=False, controllers=[TOY])
    header, plain = (built / "toy.h").read_text(), (without / "toy.h").read_text()
    assert plain[plain.index("#define TOY_NQ") : plain.index("#ifdef __cplusplus\n}")] in header


def _toy_with(**changes) -> Controller:
    fields = {
        "class_name": TOY.class_name,
        "step": TOY.step,
        "period": TOY.period,
        "state_size": TOY.state_size,
        "init": TOY.init,
        "flags": TOY.flags,
        "views": TOY.views,
        **changes,
    }
    return Controller(**fields)


@pytest.mark.parametrize(
    "controller, message",
    [
        (_toy_with(step="nope"), "step kernel 'nope' is not among"),
        (_toy_with(state_size=5), "input 'state' of 'toy_step' holds 6, the state 5"),
        (_toy_with(flags=("boost", "hold")), "has inputs"),
        (_toy_with(flags=("hold",)), "has inputs"),
        (_toy_with(views=(StateView("K", 4, 2, 2, ""),)), "is not inside the state of 6"),
        (_toy_with(views=(StateView("step", 0, 1, 1, ""),)), "attribute names repeat or are reserved"),
        (_toy_with(class_name="toy_step"), "names repeat"),
        (_toy_with(class_name="Mapping"), "reserved"),
        (_toy_with(period=0.0), "is not positive"),
        (_toy_with(init="toy_step"), "init kernel 'toy_step' has inputs"),
    ],
)
def test_broken_controllers_are_internal_errors(tmp_path, controller, message):
    with pytest.raises(KernelError, match=re.escape(message)):
        build.emit(tmp_path / "toy", "toy", toy_kernels(), nq=2, compile=False, controllers=[controller])
