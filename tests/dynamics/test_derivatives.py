"""The derivative functions against central finite differences of robotgen's own kernels
(independent of AD): a formulas leaf (where Pinocchio has no counterpart), the planar
two-link chain, and the discrete model under both integrators; and which modules offer them
(the spec's `derivatives` section)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.model.chain import Body, Joint, KinematicTree
from robotgen.model.derivatives import RK4, SEMI_IMPLICIT_EULER, DerivativeSettings
from robotgen.symbolic import leaf_kernels

SPECS = Path(__file__).resolve().parents[2] / "specs"
DERIVATIVES = (
    "inverse_dynamics_derivatives",
    "forward_dynamics_derivatives",
    "mass_inverse",
    "discrete_dynamics",
    "discrete_dynamics_derivatives",
)
H = 1e-6


def central(f, x: np.ndarray) -> np.ndarray:
    """d f/dx by central differences, columns by entry of x."""
    return np.stack([(np.asarray(f(x + H * e)) - np.asarray(f(x - H * e))) / (2 * H) for e in np.eye(len(x))], axis=-1)


def assert_close(a, b, rel=1e-6):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert np.abs(a - b).max() <= rel * max(1.0, np.abs(b).max()), (a, b)


@pytest.mark.parametrize("spec", ["styx_finger.yaml", "two_link.yaml", "puma560.yaml"])
def test_dynamics_derivatives_match_finite_differences(build_module, spec):
    m = build_module(SPECS / spec)
    assert set(DERIVATIVES) <= set(m.info()["functions"])
    rng = np.random.default_rng(3)
    n = m.nq
    for _ in range(20):
        q, qd, x = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n) * 3
        dq, dqd = m.inverse_dynamics_derivatives(q, qd, x)
        assert_close(dq, central(lambda v: m.inverse_dynamics(v, qd, x), q))
        assert_close(dqd, central(lambda v: m.inverse_dynamics(q, v, x), qd))
        fq, fqd, ftau = m.forward_dynamics_derivatives(q, qd, x)
        assert_close(fq, central(lambda v: m.forward_dynamics(v, qd, x), q))
        assert_close(fqd, central(lambda v: m.forward_dynamics(q, v, x), qd))
        assert_close(ftau, central(lambda v: m.forward_dynamics(q, qd, v), x))
        assert_close(m.mass_inverse(q) @ m.mass(q), np.eye(n), 1e-12)


@pytest.mark.parametrize("spec", ["styx_finger.yaml", "two_link.yaml", "puma560.yaml"])
def test_semi_implicit_euler_step_and_its_jacobians(build_module, spec):
    m = build_module(SPECS / spec)
    rng = np.random.default_rng(4)
    n, dt = m.nq, 0.01
    for _ in range(20):
        q, qd, tau = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        qd_next = qd + dt * m.forward_dynamics(q, qd, tau)
        for got, expected in zip(m.discrete_dynamics(q, qd, tau, dt), (q + dt * qd_next, qd_next)):
            assert_close(got, expected, 1e-14)
        q1, qd1, A, B = m.discrete_dynamics_derivatives(q, qd, tau, dt)

        def step(x, u=tau):
            return np.concatenate(m.discrete_dynamics(x[:n], x[n:], u, dt))

        assert_close(np.concatenate([q1, qd1]), step(np.concatenate([q, qd])), 1e-14)
        assert_close(A, central(step, np.concatenate([q, qd])))
        assert_close(B, central(lambda u: step(np.concatenate([q, qd]), u), tau))


def planar_two_link() -> KinematicTree:
    def joint(i, a):
        origin = np.eye(4)
        origin[0, 3] = a
        body = Body(1.0 + 0.3 * i, np.array([0.3, 0.02, 0.0]), np.diag([0.01, 0.05, 0.06]))
        return Joint(f"j{i}", "revolute", i - 1, origin, np.array([0.0, 0.0, 1.0]), body, viscous=0.1)

    return KinematicTree("two", (joint(0, 0.0), joint(1, 0.6)), 1, np.eye(4), np.array([0.0, -9.81, 0.0]))


def test_rk4_step_and_its_jacobians():
    tree = planar_two_link()
    f = {k.name: k.function for k in leaf_kernels(tree, derivatives=DerivativeSettings(True, RK4))}
    n, dt = tree.nq, 0.02
    qdd = f["forward_dynamics"]

    def rk4(x, u):
        def rate(y):
            return np.concatenate([y[n:], np.array(qdd(y[:n], y[n:], u)).ravel()])

        k1 = rate(x)
        k2 = rate(x + dt / 2 * k1)
        k3 = rate(x + dt / 2 * k2)
        k4 = rate(x + dt * k3)
        return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def step(x, u):
        return np.concatenate([np.array(v).ravel() for v in f["discrete_dynamics"](x[:n], x[n:], u, dt)])

    rng = np.random.default_rng(5)
    for _ in range(10):
        x, u = rng.normal(size=2 * n), rng.normal(size=n)
        assert_close(step(x, u), rk4(x, u), 1e-14)
        q1, qd1, A, B = (np.array(v) for v in f["discrete_dynamics_derivatives"](x[:n], x[n:], u, dt))
        assert_close(np.concatenate([q1.ravel(), qd1.ravel()]), rk4(x, u), 1e-14)
        assert_close(A.reshape(2 * n, 2 * n), central(lambda y: rk4(y, u), x))
        assert_close(B.reshape(2 * n, n), central(lambda v: rk4(x, v), u))


def names(tree, settings) -> set[str]:
    return {k.name for k in leaf_kernels(tree, derivatives=settings)}


def test_the_panda_derivatives_are_loops():
    """The Panda's derivatives pass 3000 operations: its derivative kernels are schedules
    (tests/dynamics/test_urdf_pinocchio.py checks them against Pinocchio's)."""
    from robots import PANDA, robots_dir

    from robotgen.frontend.urdf import read_urdf

    tree = read_urdf(str(robots_dir() / PANDA[0]), PANDA[1]).tree
    kernels = {k.name: k for k in leaf_kernels(tree, derivatives=DerivativeSettings())}
    for name in ("inverse_dynamics_derivatives", "forward_dynamics_derivatives", "discrete_dynamics_derivatives"):
        assert kernels[name].schedule is not None, name


def test_which_modules_offer_derivatives():
    tree = planar_two_link()
    assert set(DERIVATIVES) | {"jacobian_derivative"} <= names(tree, DerivativeSettings())
    assert not set(DERIVATIVES) & names(tree, DerivativeSettings(include=False))
    assert not set(DERIVATIVES) & names(tree, None)
    assert DerivativeSettings().included(12) and not DerivativeSettings().included(13)
    assert DerivativeSettings(include=True).included(30) and DerivativeSettings(include=True).when_asked()
    assert DerivativeSettings().when_asked() is None  # a root law's chain: only on request


def test_jacobian_derivative_times_qd_is_jacobian_dot_qd():
    tree = planar_two_link()
    f = {k.name: k.function for k in leaf_kernels(tree, derivatives=DerivativeSettings())}
    rng = np.random.default_rng(6)
    for _ in range(10):
        q, qd = rng.normal(size=2), rng.normal(size=2)
        Jdot = np.array(f["jacobian_derivative"](q, qd)).reshape(6, 2)
        assert_close(Jdot @ qd, np.array(f["jacobian_dot_qd"](q, qd)).ravel(), 1e-12)
        J = lambda v: np.array(f["jacobian"](v)).reshape(6, 2)  # noqa: E731
        assert_close(Jdot, (J(q + H * qd) - J(q - H * qd)) / (2 * H))


def write(tmp_path, text: str) -> str:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return str(path)


def test_derivatives_section_is_read_and_checked(tmp_path):
    base = (SPECS / "two_link.yaml").read_text()
    system = load_system(write(tmp_path, base + "derivatives: {integrator: rk4}\n"))
    assert system.derivatives == DerivativeSettings(None, RK4)
    assert load_system(write(tmp_path, base)).derivatives == DerivativeSettings(None, SEMI_IMPLICIT_EULER)
    with pytest.raises(UserErrors) as bad:
        load_system(write(tmp_path, base + "derivatives: {integrator: euler}\n"))
    assert "spec.yaml:" in str(bad.value) and "euler" in str(bad.value)
    tree_spec = (SPECS / "styx_high_ct.yaml").read_text() + "derivatives: {include: true}\n"
    assert load_system(write(tmp_path, tree_spec)).derivatives.include


def test_a_robot_trees_plant_derivatives_match_finite_differences(build_module, tmp_path):
    """A robot tree (the Styx hand grasping an object) asks for derivatives: its module gets
    plant_dynamics_derivatives, checked by central differences of its plant_dynamics."""
    spec = tmp_path / "styx_high_ct_derivatives.yaml"
    text = (SPECS / "styx_high_ct.yaml").read_text().replace("name: styx_high_ct", "name: styx_high_ct_derivatives")
    spec.write_text(text + "derivatives: {include: true}\n")
    m = build_module(spec)
    plain = build_module(SPECS / "styx_high_ct.yaml")
    assert not hasattr(plain, "plant_dynamics_derivatives")  # only when asked
    rng = np.random.default_rng(9)
    theta0 = np.array([2.04, 0.31, 1.10, 2.83])  # near a grasp
    n_v = len(m.plant_velocity(theta0, np.zeros(4)))
    for _ in range(10):
        theta, v, tau = theta0 + 0.05 * rng.normal(size=4), rng.normal(size=n_v) * 0.1, rng.normal(size=4)
        got = m.plant_dynamics_derivatives(theta, v, tau)

        def f(th=theta, vv=v, u=tau):
            return np.concatenate(m.plant_dynamics(th, vv, u))

        d_theta = central(lambda x: f(th=x), theta)
        d_v = central(lambda x: f(vv=x), v)
        d_tau = central(lambda x: f(u=x), tau)
        assert_close(got[0], d_theta[:4])
        assert_close(got[1], d_v[:4])
        assert_close(got[2], d_theta[4:])
        assert_close(got[3], d_v[4:])
        assert_close(got[4], d_tau[4:])
        assert_close(d_tau[:4], np.zeros((4, 4)), 1e-9)  # theta_dot does not read tau


def test_trajectory_optimisation_example_swings_the_arm_up(build_module):
    """examples/trajectory_optimisation.py's iLQR with the generated A, B reaches the upright
    posture within the torque limit, and takes the same iterates as with finite differences (to 1e-4: their error grows in
    the steep iterations)."""
    import importlib.util

    path = Path(__file__).resolve().parents[2] / "examples" / "trajectory_optimisation.py"
    spec = importlib.util.spec_from_file_location("trajectory_optimisation", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    arm = build_module(SPECS / "two_link.yaml")
    X, U, history, _, _ = example.ilqr(arm, example.exact_jacobians, iterations=30)
    _, _, history_fd, _, _ = example.ilqr(arm, example.finite_difference_jacobians, iterations=30)
    np.testing.assert_allclose(history, history_fd, rtol=1e-4)
    assert history[-1] < 1e-3 * history[0]
    assert np.abs(U).max() <= example.LIMIT
    assert abs(X[-1, 0] - np.pi / 2) < 0.05 and np.abs(X[-1, 1:]).max() < 0.1
