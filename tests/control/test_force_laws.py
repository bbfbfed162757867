"""The force laws' torques against their closed forms at random states, and their settings.

The arm of specs/impedance_arm.yaml and specs/hybrid_arm.yaml is a planar two-link (Spong,
Hutchinson & Vidyasagar sec. 7.4.2; tests/dynamics/test_closed_form.py) whose tip (x, y) is
the controlled node. Its numbers are read from the YAML here, and M, C qd, N, the tip's J and
Jdot qd written out by hand. A force F on the tip node reaches the joints as J^T F, and the
node's attributes are M_x = J^-T M J^-1, C_x xd = J^-T (C qd - M J^-1 Jdot qd), N_x = J^-T N
(eqs 3.4-3.6 with A = J^-1), so a law that writes F = M_x a + C_x xd + N_x + F' gives

    tau = M J^-1 (a - Jdot qd) + C qd + N + J^T F'.

The sensed force on the tip is F_s = J^-T tau_sensed (eq 3.7 with A = J^-1). The internal-force
PI loop is checked on specs/styx_squeeze.yaml: what it adds to the torques is J_f^T H^T of what it
adds to the squeeze (eqs 5.2-5.3), its error the squeeze sensed through H J_f^-T (eq 5.5)."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from reference import const

from robotgen.cli import main

ROOT = Path(__file__).resolve().parents[2]
IMPEDANCE, HYBRID, SQUEEZE = (ROOT / "specs" / f"{n}.yaml" for n in ("impedance_arm", "hybrid_arm", "styx_squeeze"))
N_STATES = 40


def build(tmp_path: Path, base: Path, name: str, change=None):
    data = yaml.safe_load(base.read_text())
    data["name"] = name
    if change is not None:
        change(data)
    spec = tmp_path / f"{name}.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / name
    assert main(["build", str(spec), "-o", str(out), "-q"]) == 0
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(out))


class TwoLink:
    """The arm's closed forms, from the spec's numbers (standard DH, the link frame at its
    distal end: lc = a + com_x)."""

    def __init__(self, spec: Path):
        chain = yaml.safe_load(spec.read_text())["nodes"]["arm"]["define"]["chain"]
        j1, j2 = chain["joints"]
        self.l1, self.l2 = const(j1["dh"]["a"]), const(j2["dh"]["a"])
        self.m1, self.m2 = const(j1["link"]["mass"]), const(j2["link"]["mass"])
        self.lc1, self.lc2 = self.l1 + const(j1["link"]["com"][0]), self.l2 + const(j2["link"]["com"][0])
        self.I1, self.I2 = const(j1["link"]["inertia"]["izz"]), const(j2["link"]["inertia"]["izz"])
        self.gx, self.gy = (const(g) for g in chain["gravity"][:2])

    def M(self, q):
        c2 = np.cos(q[1])
        m11 = (
            self.m1 * self.lc1**2
            + self.m2 * (self.l1**2 + self.lc2**2 + 2 * self.l1 * self.lc2 * c2)
            + self.I1
            + self.I2
        )
        m12 = self.m2 * (self.lc2**2 + self.l1 * self.lc2 * c2) + self.I2
        return np.array([[m11, m12], [m12, self.m2 * self.lc2**2 + self.I2]])

    def Cqd(self, q, qd):
        h = -self.m2 * self.l1 * self.lc2 * np.sin(q[1])
        return np.array([h * qd[1] * qd[0] + h * (qd[0] + qd[1]) * qd[1], -h * qd[0] ** 2])

    def N(self, q):
        s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q[0] + q[1]), np.cos(q[0] + q[1])
        d2 = -self.m2 * self.lc2 * (-self.gx * s12 + self.gy * c12)
        return np.array([-(self.m1 * self.lc1 + self.m2 * self.l1) * (-self.gx * s1 + self.gy * c1) + d2, d2])

    def tip(self, q):
        return np.array(
            [
                self.l1 * np.cos(q[0]) + self.l2 * np.cos(q[0] + q[1]),
                self.l1 * np.sin(q[0]) + self.l2 * np.sin(q[0] + q[1]),
            ]
        )

    def J(self, q):
        s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q[0] + q[1]), np.cos(q[0] + q[1])
        return np.array(
            [[-self.l1 * s1 - self.l2 * s12, -self.l2 * s12], [self.l1 * c1 + self.l2 * c12, self.l2 * c12]]
        )

    def Jdot_qd(self, q, qd):
        w12 = qd[0] + qd[1]
        return np.array(
            [
                -self.l1 * np.cos(q[0]) * qd[0] ** 2 - self.l2 * np.cos(q[0] + q[1]) * w12**2,
                -self.l1 * np.sin(q[0]) * qd[0] ** 2 - self.l2 * np.sin(q[0] + q[1]) * w12**2,
            ]
        )

    def torque(self, q, qd, a, F):
        """tau for F = M_x a + C_x xd + N_x + F on the tip node (module docstring)."""
        return (
            self.M(q) @ np.linalg.solve(self.J(q), a - self.Jdot_qd(q, qd))
            + self.Cqd(q, qd)
            + self.N(q)
            + self.J(q).T @ F
        )


def random_spd(rng, n=2):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def states(rng):
    """Random arm states away from the straight arm (q2 = 0, pi), and a written trajectory."""
    for _ in range(N_STATES):
        q = np.array([rng.uniform(-np.pi, np.pi), rng.choice([-1, 1]) * rng.uniform(0.3, 2.8)])
        yield (
            q,
            rng.normal(size=2),
            rng.uniform(-1, 1, 2),
            rng.normal(size=2),
            rng.normal(size=2) * 3,
            rng.normal(size=2) * 5,
            rng.normal(size=2) * 4,
        )


def test_impedance_torque_is_the_closed_form(tmp_path):
    """a* = xdd_d + M_d^-1 (F_d - F_s + D (xd_d - xd) + K (x_d - x)), F = M_x a* + C_x xd + N_x + F_s,
    with K a full matrix, D a diagonal and M_d a number, at random values of each."""

    def forms(d):
        d["nodes"]["press"]["control"]["impedance"].update(
            stiffness=[[400, 50], [50, 300]], damping=[80, 60], inertia=2.0
        )

    module = build(tmp_path, IMPEDANCE, "imp_closed_form", forms)
    arm = TwoLink(IMPEDANCE)
    assert set(module.parameters) == {"press_stiffness", "press_damping", "press_inertia"}
    rng = np.random.default_rng(1)
    worst = 0.0
    for q, qd, x_d, v_d, a_d, F_d, tau_s in states(rng):
        K, D, m = random_spd(rng) * 100, np.diag(rng.uniform(1, 100, 2)), rng.uniform(0.5, 5)
        tau = module.servo_step(
            q, qd, x_d, v_d, a_d, F_d, tau_s, press_stiffness=K, press_damping=np.diag(D), press_inertia=m
        )
        J = arm.J(q)
        F_s = np.linalg.solve(J.T, tau_s)
        a = a_d + (F_d - F_s + D @ (v_d - J @ qd) + K @ (x_d - arm.tip(q))) / m
        expect = arm.torque(q, qd, a, F_s)
        worst = max(worst, np.abs(tau - expect).max() / np.abs(expect).max())
    assert worst < 1e-11, worst


def test_impedance_without_inertia_reads_no_force(tmp_path):
    """Without inertia the robot keeps its own (M_d = M): F = M_x xdd_d + C_x xd + N_x + D e' + K e
    + F_d, and the servo step takes no tau_sensed."""
    module = build(
        tmp_path, IMPEDANCE, "imp_own_inertia", lambda d: d["nodes"]["press"]["control"]["impedance"].pop("inertia")
    )
    assert "tau_sensed" not in module.servo_step.__doc__ and not hasattr(module, "plant_sensed_forces")
    arm = TwoLink(IMPEDANCE)
    rng = np.random.default_rng(2)
    for q, qd, x_d, v_d, a_d, F_d, _ in states(rng):
        K, D = rng.uniform(1, 900), rng.uniform(1, 90)
        tau = module.servo_step(q, qd, x_d, v_d, a_d, F_d, press_stiffness=K, press_damping=D)
        spring = D * (v_d - arm.J(q) @ qd) + K * (x_d - arm.tip(q))
        np.testing.assert_allclose(tau, arm.torque(q, qd, a_d, spring + F_d), rtol=1e-11, atol=1e-11)


def test_hybrid_torque_and_state_are_the_closed_form(tmp_path):
    """a* = S (xdd_d + Kv e' + Kp e) - (I - S) Kv xd, e_f = (I - S) (F_d - F_s), z+ = z + dt e_f,
    F = M_x a* + C_x xd + N_x + F_d + kf e_f + ki z+; z+ is the next state. S with entries
    between 0 and 1 too (the bounds allow a blend)."""
    module = build(tmp_path, HYBRID, "hyb_closed_form")
    arm = TwoLink(HYBRID)
    assert set(module.parameters) == {"slide_kp", "slide_kv", "slide_selection", "slide_kf", "slide_ki"}
    np.testing.assert_array_equal(module.servo_init(np.array([0.3, 1.0]), np.ones(2)), np.zeros(2))
    rng = np.random.default_rng(3)
    worst = 0.0
    for q, qd, x_d, v_d, a_d, F_d, tau_s in states(rng):
        s = rng.choice([np.array([0.0, 1.0]), np.array([1.0, 0.0]), rng.uniform(0, 1, 2)])
        kp, kv, kf, ki = rng.uniform(1, 900), rng.uniform(1, 60), rng.uniform(0, 2), rng.uniform(0, 50)
        z, dt = rng.normal(size=2), rng.uniform(1e-4, 1e-2)
        tau, z_next = module.servo_step(
            q,
            qd,
            x_d,
            v_d,
            a_d,
            F_d,
            tau_s,
            z,
            np.array([dt]),
            slide_kp=kp,
            slide_kv=kv,
            slide_selection=s,
            slide_kf=kf,
            slide_ki=ki,
        )
        J = arm.J(q)
        S, free = np.diag(s), np.eye(2) - np.diag(s)
        xd = J @ qd
        a = S @ (a_d + kv * (v_d - xd) + kp * (x_d - arm.tip(q))) - free @ (kv * xd)
        e = free @ (F_d - np.linalg.solve(J.T, tau_s))
        np.testing.assert_allclose(z_next, z + dt * e, rtol=1e-12, atol=1e-12)
        expect = arm.torque(q, qd, a, F_d + kf * e + ki * (z + dt * e))
        worst = max(worst, np.abs(tau - expect).max() / np.abs(expect).max())
    assert worst < 1e-11, worst


def test_folded_force_laws_equal_their_runtime_defaults(tmp_path):
    rng = np.random.default_rng(4)
    for base, name in ((IMPEDANCE, "imp"), (HYBRID, "hyb")):
        runtime = build(tmp_path, base, f"{name}_runtime")
        folded = build(
            tmp_path, base, f"{name}_folded", lambda d: d["nodes"][d["root"]]["control"].update(gains="folded")
        )
        assert not hasattr(folded, "parameters")
        q, qd, x_d, v_d, a_d, F_d, tau_s = next(states(rng))
        args = [q, qd, x_d, v_d, a_d, F_d, tau_s] + ([np.ones(2), np.array([1e-3])] if name == "hyb" else [])
        for a, b in zip(np.atleast_1d(runtime.servo_step(*args)), np.atleast_1d(folded.servo_step(*args))):
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


def styx_tips(theta):
    """The Styx fingers' Jacobians (absolute link angles, l = 0.1 m) and the squeeze direction
    H = (u, -u) / sqrt(2) of the grasp, u from the left fingertip to the right one."""
    l = 0.1
    Js = [
        np.array([[-l * np.sin(a), -l * np.sin(b)], [l * np.cos(a), l * np.cos(b)]]) for a, b in (theta[:2], theta[2:])
    ]
    tips = [
        np.array([-0.1 + l * np.cos(theta[0]) + l * np.cos(theta[1]), l * np.sin(theta[0]) + l * np.sin(theta[1])]),
        np.array([0.1 + l * np.cos(theta[2]) + l * np.cos(theta[3]), l * np.sin(theta[2]) + l * np.sin(theta[3])]),
    ]
    u = (tips[1] - tips[0]) / np.linalg.norm(tips[1] - tips[0])
    return Js, np.r_[u, -u] / np.sqrt(2)


def test_internal_force_pi_is_the_closed_form(build_module):
    """The squeeze loop adds kf e + ki z+ to the squeeze f_d it writes, e = f_d - H J_f^-T tau_sensed,
    z+ = z + dt e (the state's last entry: ct_hand is the root, its integral its last block), and
    that reaches the joints as J_f^T H^T (kf e + ki z+) (eqs 5.2-5.5): the torques with the
    loop less those with kf = ki = 0 at the same state."""
    module = build_module(SQUEEZE)
    assert module.parameters["ct_hand_kf_internal"] == 0.5 and module.parameters["ct_hand_ki_internal"] == 40.0
    rng = np.random.default_rng(5)
    f_d = 6.0
    for _ in range(N_STATES):
        theta = module.plant_inverse(np.array([0.0, 0.12, 0.0]) + rng.uniform(-0.01, 0.01, 3))
        theta_dot = rng.normal(size=4) * 0.1
        x_e, xd_e, xdd_e, f_e = (
            np.array([0.0, 0.12, 0.0]),
            rng.normal(size=3) * 0.1,
            rng.normal(size=3),
            rng.normal(size=3),
        )
        tau_s, dt = rng.normal(size=4) * 0.3, 1e-3
        state = module.servo_init(theta, theta_dot)
        state[-1] = rng.normal()
        kf, ki = rng.uniform(0, 0.99), rng.uniform(0, 900)
        args = (theta, theta_dot, x_e, xd_e, xdd_e, f_e, tau_s, state, np.array([dt]))
        tau, state_next = module.servo_step(*args, ct_hand_kf_internal=kf, ct_hand_ki_internal=ki)
        tau0, state0 = module.servo_step(*args, ct_hand_kf_internal=0.0, ct_hand_ki_internal=0.0)
        Js, H = styx_tips(theta)
        sensed = H @ np.concatenate([np.linalg.solve(J.T, tau_s[2 * k : 2 * k + 2]) for k, J in enumerate(Js)])
        e = f_d - sensed
        np.testing.assert_allclose(state_next[-1], state[-1] + dt * e, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(state_next[:-1], state0[:-1], rtol=1e-12, atol=1e-12)
        extra = H * (kf * e + ki * (state[-1] + dt * e))
        expect = np.concatenate([J.T @ extra[2 * k : 2 * k + 2] for k, J in enumerate(Js)])
        np.testing.assert_allclose(tau - tau0, expect, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(expect).max()))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robotgen", *args], capture_output=True, text=True, cwd=ROOT)


def check_fails(tmp_path: Path, base: Path, name: str, change, *expected: str) -> None:
    data = yaml.safe_load(base.read_text())
    data["name"] = name
    change(data)
    spec = tmp_path / f"{name}.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    r = run_cli("check", str(spec))
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"{spec}:"), r.stderr
    for text in expected:
        assert text in r.stderr, r.stderr


@pytest.mark.parametrize(
    "case",
    [
        (
            "imp_kp",
            IMPEDANCE,
            lambda d: d["nodes"]["press"]["control"].update(kp=100),
            ["law impedance takes no kp (its stiffness and damping go under impedance)"],
        ),
        ("imp_missing", IMPEDANCE, lambda d: d["nodes"]["press"]["control"]["impedance"].pop("damping"), ["damping"]),
        (
            "imp_negative",
            IMPEDANCE,
            lambda d: d["nodes"]["press"]["control"]["impedance"].update(stiffness=[400, -1]),
            ["stiffness -1 must be at least 0 (K of the target impedance)"],
        ),
        (
            "imp_indefinite",
            IMPEDANCE,
            lambda d: d["nodes"]["press"]["control"]["impedance"].update(inertia=[[1, 2], [2, 1]]),
            ["inertia must be positive definite (M_d of the target impedance)"],
        ),
        (
            "hyb_selection",
            HYBRID,
            lambda d: d["nodes"]["slide"]["control"]["hybrid"].update(selection=[0, 1, 1]),
            ["expected 2 entries, one per coordinate of 'tip' (arm_x, arm_y)"],
        ),
        (
            "hyb_blend",
            HYBRID,
            lambda d: d["nodes"]["slide"]["control"]["hybrid"].update(selection=[0, 1.5]),
            ["selection 1.5 must be in [0, 1]"],
        ),
        (
            "hyb_wrong_block",
            HYBRID,
            lambda d: d["nodes"]["slide"]["control"].update(impedance={"stiffness": 1, "damping": 1}),
            ["settings of law impedance; this node's law is hybrid"],
        ),
        ("hyb_no_kp", HYBRID, lambda d: d["nodes"]["slide"]["control"].pop("kp"), ["missing required key 'kp'"]),
        (
            "sq_pd",
            SQUEEZE,
            lambda d: d["nodes"]["pd_left"]["control"].update(ki_internal=5),
            ["law pd passes internal forces up unresolved"],
        ),
        (
            "sq_fast",
            SQUEEZE,
            lambda d: d["nodes"]["ct_hand"]["control"].update(ki_internal=1500),
            ["ki_internal 1500 with dt = 0.001 s", "< 2 (1 - kf_internal) = 1, got 1.5", "below 1000"],
        ),
        (
            "sq_fixed_mass",
            SQUEEZE,
            lambda d: d["nodes"]["box"]["define"]["rigid_body"]["planar"].update(mass=0.2),
            ["payload 'box''s mass must be a run-time parameter (mass: {runtime: 0.2}"],
        ),
        (
            "sq_com",
            SQUEEZE,
            lambda d: d["simulation"]["payload_change"].update(com=[0, 0, 0]),
            ["com applies to a hand controller's"],
        ),
        (
            "wall_node",
            IMPEDANCE,
            lambda d: d["simulation"]["wall"].update(node="arm"),
            ["node 'arm' must have 2 or 3 coordinates in metres", "shoulder, elbow [rad, rad]"],
        ),
        (
            "wall_payload",
            SQUEEZE,
            lambda d: d["simulation"].update(wall={"node": "box", "point": [0, 0], "normal": [1, 0]}),
            ["'box' is a payload; a wall touches a robot's point"],
        ),
        (
            "wall_normal",
            IMPEDANCE,
            lambda d: d["simulation"]["wall"].update(normal=[0, 0]),
            ["the wall's normal must not be zero"],
        ),
        (
            "wall_point",
            IMPEDANCE,
            lambda d: d["simulation"]["wall"].update(point=[1, 0, 0]),
            ["expected 2 entries, one per coordinate of 'tip': arm_x, arm_y; got 3"],
        ),
        (
            "force_size",
            HYBRID,
            lambda d: d["simulation"].update(force=[10]),
            ["expected 2 entries (one per velocity coordinate of 'slide': arm_x, arm_y), got 1"],
        ),
        (
            "hand_wall",
            ROOT / "specs" / "puma560_rmac.yaml",
            lambda d: d["simulation"].update(wall={"node": "arm", "point": [0, 0], "normal": [1, 0]}),
            ["simulation.wall: 'wall' applies to robot trees"],
        ),
        (
            "hand_payload",
            ROOT / "specs" / "puma560_rmac.yaml",
            lambda d: d["simulation"]["payload_change"].update(payload="arm"),
            ["a hand controller's payload is a point mass in its hand"],
        ),
        (
            "rate_force",
            ROOT / "specs" / "puma560_rmrc.yaml",
            lambda d: d["simulation"].update(force=[1.0]),
            ["simulation.force: 'force' applies to robot trees of torque controllers"],
        ),
    ],
    ids=lambda c: c[0],
)
def test_force_settings_are_checked(tmp_path, case):
    name, base, change, expected = case
    check_fails(tmp_path, base, name, change, *expected)


def test_force_law_parameters_are_bounded_at_run_time(build_module):
    module = build_module(HYBRID)
    args = [
        np.array([1.0, -1.3]),
        np.zeros(2),
        np.ones(2),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2),
        np.array([1e-3]),
    ]
    with pytest.raises(ValueError, match=r"selection 2 must be in \[0, 1\]"):
        module.servo_step(*args, slide_selection=np.array([0.0, 2.0]))
    with pytest.raises(ValueError, match="force gain ki -1 must be at least 0"):
        module.servo_step(*args, slide_ki=-1.0)
    squeeze = build_module(SQUEEZE)
    theta = squeeze.plant_inverse(np.array([0.0, 0.12, 0.0]))
    with pytest.raises(ValueError, match="gain ki_internal -1 must be at least 0"):
        squeeze.servo_step(
            theta,
            np.zeros(4),
            np.zeros(3),
            np.zeros(3),
            np.zeros(3),
            np.zeros(3),
            np.zeros(4),
            squeeze.servo_init(theta, np.zeros(4)),
            np.array([1e-3]),
            ct_hand_ki_internal=-1.0,
        )


def test_python_api_hybrid_snippet_prints_what_it_says(build_module):
    """docs/python-api.md's step of the hybrid arm: the state and torques its comment gives."""
    build_module(HYBRID)  # imported as hybrid_arm, which the snippet imports
    api = (ROOT / "docs" / "python-api.md").read_text()
    snippet = next(part.partition("```")[0] for part in api.split("```python\n")[1:] if "import hybrid_arm" in part)
    names: dict = {}
    exec(compile(snippet, "<python-api.md>", "exec"), names)
    state, tau = names["state"], names["tau"]
    said = snippet.split("# state = ")[1]
    assert said.startswith(f"[{state[0]:g}, {state[1]:g}]")
    assert f"tau = [{tau[0]:.4f}, {tau[1]:.4f}]" in said
