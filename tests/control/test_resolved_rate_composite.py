"""Resolved motion rate control of a composite robot: `control: {law: resolved_rate, robot: R}`
with R an ATTACH node (or a control/attach tree). The command is a velocity of R in R's own
coordinates; the leaves' joint rates are the tree's velocity map.

The Styx hand of specs/styx_high_ct.yaml with its computed-torque root replaced by a
resolved_rate controller over `hand` (the box pose x, y, psi) is compiled and its generated
steps integrated (RK4 on the leaf angles, theta_dot = rate_step / position_step). The other
variants (the fingers' frame change, a multilevel tree with controllers below, three-link
fingers with internal motions, damping and rate limits) evaluate the CasADi graphs the C is
printed from. Every test prints its numbers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from test_resolved_rate_chain import Graphs, rk4

from robotgen.errors import UserErrors
from robotgen.frontend import load_system

ROOT = Path(__file__).resolve().parents[2]
SPECS = ROOT / "specs"
CONTACTS = np.array([[-0.05, 0.0], [0.05, 0.0]])  # the box's contact points, box frame
START = np.array([0.0, 0.12, 0.0])  # the box pose of the Styx examples


def variant(
    tmp: Path,
    source: str,
    name: str,
    robot: str,
    settings: dict | None = None,
    keep: tuple[str, ...] | None = None,
    drop: tuple[str, ...] = ("ct_hand",),
) -> Path:
    """specs/<source>.yaml with its root replaced by `rr: control: {law: resolved_rate, robot}`:
    ``drop`` nodes removed (the old root), or only ``keep`` nodes kept."""
    data = yaml.safe_load((SPECS / f"{source}.yaml").read_text())
    data["name"], data["root"] = name, "rr"
    data.pop("simulation", None)
    nodes = data["nodes"]
    for n in list(nodes):
        if (keep is not None and n not in keep) or n in drop:
            del nodes[n]
    control = {"robot": robot, "law": "resolved_rate"}
    if settings:
        control["resolved_rate"] = settings
    nodes["rr"] = {"control": control}
    spec = tmp / f"{name}.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    return spec


def h_inverse(x: np.ndarray) -> np.ndarray:
    """Fingertip positions (xl, yl, xr, yr) of the box pose (x, y, psi): the grasp's h^-1."""
    c, s = np.cos(x[2]), np.sin(x[2])
    R = np.array([[c, -s], [s, c]])
    return np.concatenate([x[:2] + R @ p for p in CONTACTS])


@pytest.fixture(scope="module")
def hand(build_module, tmp_path_factory):
    return build_module(variant(tmp_path_factory.mktemp("styx_rr"), "styx_high_ct", "styx_rr_hand", "hand"))


# -- rate control ----------------------------------------------------------------------
def test_box_moves_with_the_commanded_velocity_and_stays_grasped(hand):
    """1 s at 1 kHz under a constant box velocity: the box pose (plant_position, and hand_read)
    is x0 + v t at every step and the fingertips stay on the contact points."""
    command = np.array([0.02, -0.01, 0.1])  # x, y [m/s], psi [rad/s]
    theta0 = hand.plant_inverse(START)
    x0 = hand.plant_position(theta0)
    dt, zero = 1e-3, np.zeros(4)
    worst = {"pose": 0.0, "read": 0.0, "grasp": 0.0, "xd": 0.0}

    def check(k, theta):
        t = (k + 1) * dt
        x = hand.plant_position(theta)
        x_read, xd_read = hand.hand_read(theta, hand.rate_step(theta, command)[0])
        tips = hand.fingers_read(theta, zero)[0]
        worst["pose"] = max(worst["pose"], np.abs(x - x0 - command * t).max())
        worst["read"] = max(worst["read"], np.abs(x_read - x).max())
        worst["grasp"] = max(worst["grasp"], np.abs(h_inverse(x) - tips).max())
        worst["xd"] = max(worst["xd"], np.abs(xd_read - command).max())

    theta = rk4(lambda th: hand.rate_step(th, command)[0], theta0, dt, 1000, check)
    print(
        f"\nbox {x0} -> {hand.plant_position(theta)} in 1 s: |x - (x0 + v t)| max {worst['pose']:.2e}, "
        f"|hand_read - plant_position| {worst['read']:.2e}, |h^-1(x) - fingertips| {worst['grasp']:.2e}, "
        f"|hand_read xd - command| {worst['xd']:.2e}"
    )
    assert worst["pose"] < 1e-9 and worst["read"] < 1e-12 and worst["grasp"] < 1e-9 and worst["xd"] < 1e-12
    np.testing.assert_allclose(hand.plant_position(theta), x0 + command, atol=1e-9)


def test_velocity_map_is_the_tree_of_attach_maps(hand):
    """command_jacobian (hand's rd map) is a left inverse of velocity_map, whose columns are the
    leaf rates moving the box along each coordinate (central differences of plant_position);
    the reported measures are those of the rd map restricted to the grasp-keeping leaf rates."""
    rng = np.random.default_rng(2)
    worst = {"JA": 0.0, "fd": 0.0, "w": 0.0, "cond": 0.0}
    for _ in range(10):
        x = START + rng.uniform([-0.02, -0.02, -0.3], [0.02, 0.02, 0.3])
        theta = hand.plant_inverse(x)
        A, J = hand.velocity_map(theta), hand.command_jacobian(theta)
        h = 1e-6
        fd = np.array(
            [(hand.plant_position(theta + h * a) - hand.plant_position(theta - h * a)) / (2 * h) for a in A.T]
        ).T
        U = np.linalg.svd(A, full_matrices=False)[0]  # orthonormal basis of the grasp-keeping rates
        sv = np.linalg.svd(J @ U, compute_uv=False)
        _, w, cond = hand.rate_step(theta, np.zeros(3))
        worst["JA"] = max(worst["JA"], np.abs(J @ A - np.eye(3)).max())
        worst["fd"] = max(worst["fd"], np.abs(fd - np.eye(3)).max())
        worst["w"] = max(worst["w"], abs(w[0] / np.prod(sv) - 1))
        worst["cond"] = max(worst["cond"], abs(cond[0] / (sv[0] / sv[-1]) - 1))
        # all of J's singular values would overstate it: they include the leaf rates that squeeze
        assert w[0] < np.prod(np.linalg.svd(J, compute_uv=False))
    print(
        f"\n10 poses: |J A - I| {worst['JA']:.2e}, |d plant_position / d theta A - I| {worst['fd']:.2e}, "
        f"manipulability rel. error {worst['w']:.2e}, condition rel. error {worst['cond']:.2e}"
    )
    assert worst["JA"] < 1e-12 and worst["fd"] < 1e-8 and worst["w"] < 1e-9 and worst["cond"] < 1e-7


# -- position control through rates -----------------------------------------------------
def test_position_control_brings_the_box_to_reachable_targets(hand):
    starts = [START, START + [0.015, -0.01, 0.2], START + [-0.02, 0.015, -0.25], START + [0.01, 0.02, 0.1]]
    targets = [START + [0.02, -0.015, 0.3], START + [-0.015, 0.01, -0.2], START, START + [0.0, -0.02, 0.25]]
    worst_grasp = [0.0]

    def check(k, theta):
        x = hand.plant_position(theta)
        worst_grasp[0] = max(worst_grasp[0], np.abs(h_inverse(x) - hand.fingers_read(theta, np.zeros(4))[0]).max())

    finals = []
    for x0, xt in zip(starts, targets):
        theta = rk4(lambda th: hand.position_step(th, xt)[0], hand.plant_inverse(x0), 2e-3, 1250, check)  # 2.5 s
        finals.append((np.abs(hand.plant_position(theta) - xt).max(), np.abs(hand.position_step(theta, xt)[1]).max()))
    print(
        f"\n{len(starts)} starts, horizon T = {hand.info()['rate_control']['horizon']} s, 2.5 s: final |x - target| "
        f"{', '.join(f'{a:.1e}' for a, _ in finals)}; reported error {max(b for _, b in finals):.1e}; "
        f"|h^-1(x) - fingertips| max {worst_grasp[0]:.1e}"
    )
    assert max(a for a, _ in finals) < 1e-6 and max(b for _, b in finals) < 1e-6 and worst_grasp[0] < 1e-9


def test_position_error_wraps_psi_only(hand):
    """psi (a rigid payload's angle) wraps: a target 2 pi + 0.01 away is 0.01 away; x and y
    do not."""
    theta = hand.plant_inverse(START + [0.01, 0, 0.1])
    x = hand.plant_position(theta)
    near = hand.position_step(theta, x + [0.001, 0, 0.01])
    far = hand.position_step(theta, x + [0.001, 2 * np.pi, 0.01 + 2 * np.pi])
    print(f"\nerror to target +(0.001, 2 pi, 0.01 + 2 pi): {far[1]}")
    np.testing.assert_allclose(far[1], [0.001, 2 * np.pi, 0.01], atol=1e-12)
    np.testing.assert_allclose(near[1], [0.001, 0, 0.01], atol=1e-12)
    assert hand.info()["rate_control"]["wrapped"] == ["psi"]


def test_module_functions_and_info(hand):
    info = hand.info()
    functions = info["functions"]
    for name in (
        "rate_step",
        "position_step",
        "velocity_map",
        "command_jacobian",
        "hand_read",
        "fingers_read",
        "plant_position",
        "plant_inverse",
        "hand_write",
    ):
        assert name in functions, name
    assert "servo_step" not in functions  # the torque tree's step is hand_write here
    rc = info["rate_control"]
    print(f"\n{rc}")
    assert rc["robot"] == "hand" and rc["command"] == ["x", "y", "psi"] and rc["internal_motions"] == []
    assert info["leaves"] == ["left", "right"] and info["nodes"]["rr"]["kind"] == "resolved_rate"


# -- other composite robots ------------------------------------------------------------------
def test_fingers_frame_change_node(tmp_path):
    """The fingers' frame change as the robot: the command is the fingertip velocities; no
    coordinate is known to be an angle, and the composite Jacobian is the fingers' (square)."""
    g = Graphs(variant(tmp_path, "styx_high_ct", "styx_rr_fingers", "fingers", keep=("left", "right", "fingers")))
    tips0 = h_inverse(START)
    theta0 = g.plant_inverse(tips0)
    command = np.array([0.01, 0.02, -0.015, 0.01])
    theta = rk4(lambda th: g.rate_step(th, command)[0], theta0, 1e-3, 1000)
    tips = g.plant_position(theta)
    J = g.command_jacobian(theta)
    w = g.rate_step(theta, command)[1][0]
    target = g.position_step(theta, tips + [0.0, 2 * np.pi, 0.0, 0.0])[1]
    print(f"\nfingertips {tips0} -> {tips}; manipulability {w:.6f} = |det J| {abs(np.linalg.det(J)):.6f}")
    np.testing.assert_allclose(tips, tips0 + command, atol=1e-9)
    np.testing.assert_allclose(w, abs(np.linalg.det(J)), rtol=1e-9)
    np.testing.assert_allclose(target, [0.0, 2 * np.pi, 0.0, 0.0], atol=1e-12)  # nothing wraps


def test_controllers_below_do_not_change_the_kinematics(tmp_path):
    """styx_multilevel's hand (pd controllers on the fingers, a feedforward on the frame change)
    gives the same joint rates as the plain hand."""
    plain = Graphs(variant(tmp_path, "styx_high_ct", "styx_rr_plain", "hand"))
    multi = Graphs(variant(tmp_path, "styx_multilevel", "styx_rr_multi", "hand"))
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(5):
        theta = plain.plant_inverse(START + rng.uniform(-0.02, 0.02, 3))
        command = rng.uniform(-0.05, 0.05, 3)
        for a, b in zip(plain.rate_step(theta, command), multi.rate_step(theta, command)):
            worst = max(worst, np.abs(a - b).max())
        worst = max(worst, np.abs(plain.position_step(theta, START)[0] - multi.position_step(theta, START)[0]).max())
    print(f"\nmultilevel vs plain hand: max difference {worst:.1e}")
    assert worst < 1e-13


def test_internal_motions_are_a_null_space_command(tmp_path):
    """Three-link fingers (styx_redundant): the hand's velocity is (x, y, psi, fingers_m1,
    fingers_m2). Internal-motion rates move the fingers and leave the box and the grasp
    alone; a controller that resolves them (ct_hand, resolve_internal_motion) exposes only
    (x, y, psi) and the rate controller over it commands them zero."""
    redundant = yaml.safe_load((SPECS / "styx_redundant.yaml").read_text())
    theta0 = np.array(redundant["simulation"]["theta0"])
    g = Graphs(variant(tmp_path, "styx_redundant", "styx_rr_redundant", "hand"))
    over_ct = Graphs(variant(tmp_path, "styx_redundant", "styx_rr_over_ct", "ct_hand", drop=()))
    x0 = g.plant_position(theta0)
    command = np.array([0.01, -0.01, 0.05, 0.3, -0.2])
    theta = rk4(lambda th: g.rate_step(th, command)[0], theta0, 1e-3, 1000)
    x = g.plant_position(theta)
    self_motion = rk4(lambda th: g.rate_step(th, np.r_[0, 0, 0, 0.3, -0.2])[0], theta0, 1e-3, 1000)
    tips = g.fingers_read(theta, np.zeros(6))[0]
    print(
        f"\nbox {x0} -> {x}; self-motion alone moved the joints {np.linalg.norm(self_motion - theta0):.3f} rad "
        f"and the box {np.abs(g.plant_position(self_motion) - x0).max():.1e}"
    )
    np.testing.assert_allclose(x, x0 + command[:3], atol=1e-9)
    np.testing.assert_allclose(h_inverse(x), tips, atol=1e-9)
    np.testing.assert_allclose(g.hand_read(theta, g.rate_step(theta, command)[0])[1], command, atol=1e-12)
    assert np.linalg.norm(self_motion - theta0) > 0.1
    assert np.abs(g.plant_position(self_motion) - x0).max() < 1e-9
    np.testing.assert_allclose(
        over_ct.rate_step(theta0, command[:3])[0], g.rate_step(theta0, np.r_[command[:3], 0, 0])[0], atol=1e-14
    )
    np.testing.assert_allclose(
        over_ct.position_step(theta0, x0 + 0.01)[0], g.position_step(theta0, x0 + 0.01)[0], atol=1e-14
    )


# -- singularities and rate limits ------------------------------------------------------------
def test_damping_near_stretched_fingers_keeps_rates_bounded_and_the_grasp(tmp_path):
    """Lifting the box towards the fingers' reach (tips 0.2 m from the bases at y = 0.1936):
    the velocity map blows up; damped, the box slows down short of it, rates stay bounded and
    the fingertips stay on the box."""
    settings = {"damping": {"lambda_max": 0.05, "threshold": 0.004}}
    g = Graphs(variant(tmp_path, "styx_high_ct", "styx_rr_damped", "hand", settings))
    command = np.array([0.0, 0.05, 0.0])
    stats = {"w": np.inf, "qd": 0.0, "grasp": 0.0}

    def check(k, theta):
        qd, w, _ = g.rate_step(theta, command)
        assert np.all(np.isfinite(qd))
        x = g.plant_position(theta)
        stats["w"] = min(stats["w"], w[0])
        stats["qd"] = max(stats["qd"], np.abs(qd).max())
        stats["grasp"] = max(stats["grasp"], np.abs(h_inverse(x) - g.fingers_read(theta, np.zeros(4))[0]).max())

    theta = rk4(lambda th: g.rate_step(th, command)[0], g.plant_inverse(START), 1e-3, 2000, check)
    x = g.plant_position(theta)
    print(
        f"\ndamped lift 2 s: box y {START[1]} -> {x[1]:.5f} (commanded {START[1] + 0.1:.2f}, reach 0.1936), "
        f"min manipulability {stats['w']:.2e}, max |theta_dot| {stats['qd']:.3f} rad/s, "
        f"|h^-1(x) - fingertips| {stats['grasp']:.1e}"
    )
    assert 0.185 < x[1] < 0.1936 and abs(x[0]) < 1e-9 and abs(x[2]) < 1e-9
    assert stats["qd"] < 1.0 and stats["grasp"] < 1e-9 and stats["w"] < 1e-3


def test_rate_limits_scale_the_whole_vector(tmp_path):
    g = Graphs(variant(tmp_path, "styx_high_ct", "styx_rr_limited", "hand", {"rate_limits": [1, 1, 2, 2]}))
    theta = g.plant_inverse(START)
    command = np.array([0.3, -0.2, 2.0])
    qd = g.rate_step(theta, command)[0]
    xd = g.hand_read(theta, qd)[1]
    free = g.velocity_map(theta) @ command
    scale = np.max(np.abs(free) / [1, 1, 2, 2])
    print(f"\nunlimited |theta_dot| / limit up to {scale:.3f}; box velocity {xd} for command {command}")
    assert scale > 1
    np.testing.assert_allclose(qd, free / scale, atol=1e-14)
    np.testing.assert_allclose(xd, command / scale, atol=1e-12)


# -- the spec layer ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "settings, message",
    [
        (
            {"frame": "base"},
            "'frame' applies to a chain leaf; over the composite robot 'hand' the command is its "
            "velocity in its own coordinates (x, y, psi)",
        ),
        ({"lqr": {"nominal": [0, 0, 0, 0]}}, "'lqr' applies to a chain leaf"),
        ({"redundancy": {"objective": "joint_limits"}}, "'redundancy' applies to a chain leaf"),
        ({"rate_limits": [1, 2]}, "expected 4 entries (one per joint), got 2"),
    ],
)
def test_located_errors(tmp_path, settings, message):
    spec = variant(tmp_path, "styx_high_ct", "bad", "hand", settings)
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    print(f"\n{text}")
    assert message in text and f"{spec}:" in text


def test_composite_resolved_rate_must_still_be_the_root(tmp_path):
    data = yaml.safe_load((SPECS / "styx_high_ct.yaml").read_text())
    data["nodes"]["rr"] = {"control": {"robot": "hand", "law": "resolved_rate"}}
    data["nodes"]["ct_hand"]["control"]["robot"] = "rr"
    spec = tmp_path / "inner.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    assert "a resolved_rate controller must be the root" in str(error.value)
