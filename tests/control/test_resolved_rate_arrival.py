"""Position control through rates with the remaining time of Whitney 1972's eq 11: the
`arrival` setting of law resolved_rate and its `arrival_step(q, target, remaining)`.

The PUMA 560 of specs/puma560_rmrc.yaml, with `arrival` and a horizon of 0.5 s (so that the
exponential approach is still visibly short after 2 s), is compiled; its steps run as an
ideal joint-rate servo (robotgen.simulation.approach_paths: each call's rates held over one period).
The composite robot (styx_redundant's hand) evaluates the CasADi graphs the C is printed
from. Every test prints its numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation
from test_resolved_rate_chain import Graphs, write_spec
from test_resolved_rate_composite import SPECS, h_inverse, variant

from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.simulation.approach_paths import approach_paths

PUMA_RMRC = SPECS / "puma560_rmrc.yaml"
QN = np.array([0, np.pi / 4, np.pi, 0, np.pi / 4, 0])  # the PUMA's nominal pose
LIMITS = np.array([2.0, 2.0, 2.0, 4.0, 4.0, 4.0])  # the spec's rate_limits
HORIZON = 0.5  # the copy's horizon [s]
DT = 1e-3  # the control period, and the spec's arrival.minimum_remaining [s]
T_ARRIVAL = 2.0  # [s]
DISTANCE, TURN = 0.2, np.radians(30)  # the target: 0.2 m along DIRECTION, 30 degrees about AXIS
DIRECTION = np.array([0.12, -0.08, 0.14]) / np.linalg.norm([0.12, -0.08, 0.14])  # base axes
AXIS = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])  # base axes


def rotation_vector(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_rotvec()


@pytest.fixture(scope="module")
def puma(build_module, tmp_path_factory):
    """specs/puma560_rmrc.yaml with `arrival: {minimum_remaining: DT}` and horizon 0.5 s."""
    data = yaml.safe_load(PUMA_RMRC.read_text())
    data["name"] = "puma560_rmrc_arrival"
    settings = data["nodes"]["rmrc"]["control"]["resolved_rate"]
    settings["horizon"] = HORIZON
    settings["arrival"] = {"minimum_remaining": DT}
    spec = tmp_path_factory.mktemp("puma_arrival") / "puma560_rmrc_arrival.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    return build_module(spec)


def target_pose(puma) -> np.ndarray:
    start = puma.fk(QN)
    target = start.copy()
    target[:3, 3] += DISTANCE * DIRECTION
    target[:3, :3] = Rotation.from_rotvec(TURN * AXIS).as_matrix() @ start[:3, :3]
    return target


def path_measures(puma, q: np.ndarray, t: np.ndarray, arrival_time: float) -> dict:
    """The hand's path against the ideal one (a straight line at constant speed, a fixed axis
    at a constant rate, arriving at arrival_time), from fk alone."""
    poses = puma.fk(q)
    start, target = poses[0], target_pose(puma)
    rel = poses[:, :3, 3] - start[:3, 3]
    along = rel @ DIRECTION
    speed = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1) / np.diff(t)
    turned = np.array([rotation_vector(start[:3, :3].T @ P[:3, :3]) for P in poses])  # hand axes
    planned = TURN * (start[:3, :3].T @ AXIS)
    half = len(t) // 2
    assert abs(t[half] - arrival_time / 2) < 1e-12
    return {
        "arrived": np.linalg.norm(poses[-1, :3, 3] - target[:3, 3]),
        "arrived_rot": np.linalg.norm(rotation_vector(poses[-1, :3, :3].T @ target[:3, :3])),
        "off_line": np.linalg.norm(rel - np.outer(along, DIRECTION), axis=1).max(),
        "speed": (speed.max() - speed.min()) / (DISTANCE / arrival_time),
        "half": np.linalg.norm(rel[half] - DISTANCE * DIRECTION / 2),
        "axis": np.abs(turned - np.outer(t / arrival_time, planned)).max(),
    }


# -- a chain --------------------------------------------------------------------------------
def test_the_hand_arrives_at_T_on_a_straight_line_at_constant_speed(puma):
    """0.2 m and 30 degrees in T = 2 s, at control periods of 1 and 2 ms. Re-planned with the
    remaining time, the hand moves on the line at 0.1 m/s, turns about the fixed axis at
    15 deg/s, is half way at T/2 and arrives at T. What is left is the Euler step's (the
    joints' rates held over a period while J changes): about dt^2/2 per step, which
    re-planning does not let grow, so the deviations along the way are first order in dt
    (they halve with it, bounded here by 0.02 m/s x dt) and the arrival is second order
    (the last step's only: within 1e-6 m and 1e-6 rad at dt = 2 ms). The exponential
    approach of position_step (T = horizon) is after 2 s still short by the factor
    exp(-T/horizon) = exp(-4), to first order in dt ((1 - dt/horizon)^(T/dt) exactly)."""
    target = target_pose(puma)
    results = {}
    for dt in (DT, 2 * DT):
        exponential, arrival = approach_paths(puma, QN, target, T_ARRIVAL, dt)
        m = path_measures(puma, arrival.q, arrival.t, T_ARRIVAL)
        m["scale"] = arrival.rate_scale.min()
        m["exp_position"] = exponential.distance()[-1] / exponential.distance()[0]
        m["exp_rotation"] = exponential.distance(slice(3, 6))[-1] / exponential.distance(slice(3, 6))[0]
        m["exp_short"] = exponential.distance()[-1]
        m["exp_rates"] = (np.abs(np.diff(exponential.q, axis=0)) / dt / LIMITS).max()
        results[dt] = m
        print(
            f"\ndt {dt:g} s, arrival at T = {T_ARRIVAL:g} s: |p - p_f| {m['arrived']:.2e} m, rotation left "
            f"{m['arrived_rot']:.2e} rad; off the line {m['off_line']:.2e} m, speed (max - min) / 0.1 m/s "
            f"{m['speed']:.2e}, at T/2 {m['half']:.2e} m from half way, rotation vector off the plan "
            f"{m['axis']:.2e} rad; min rate_scale {m['scale']:g}\n  exponential (horizon {HORIZON} s): error "
            f"after T {m['exp_short'] * 1e3:.2f} mm, factor {m['exp_position']:.6f} (rotation {m['exp_rotation']:.6f})"
            f"; exp(-T/horizon) {np.exp(-T_ARRIVAL / HORIZON):.6f}, (1 - dt/horizon)^(T/dt) "
            f"{(1 - dt / HORIZON) ** round(T_ARRIVAL / dt):.6f}; its rates at most {m['exp_rates']:.3f} of the limits"
        )
    fine, coarse = results[DT], results[2 * DT]
    for m, dt in ((fine, DT), (coarse, 2 * DT)):
        assert m["scale"] == 1 and m["exp_rates"] < 1  # no rate limit acted in either approach
        assert m["arrived"] < 1e-6 and m["arrived_rot"] < 1e-6
        for key in ("off_line", "half"):
            assert m[key] < 0.02 * dt, key
        assert m["speed"] < 1.0 * dt and m["axis"] < 0.05 * dt
        exact = (1 - dt / HORIZON) ** round(T_ARRIVAL / dt)
        first_order = T_ARRIVAL * dt / (2 * HORIZON**2)  # log((1 - h)^(T/dt)) = -T/horizon - T dt / 2 horizon^2
        for key in ("exp_position", "exp_rotation"):
            assert abs(m[key] / exact - 1) < 1e-3, key
            assert abs(m[key] / np.exp(-T_ARRIVAL / HORIZON) - 1) < 2 * first_order, key
        assert m["exp_short"] > 0.015 * DISTANCE  # the exponential approach has not arrived
    for key in ("off_line", "half", "speed", "axis"):  # first order: they halve with dt
        assert 1.6 < coarse[key] / fine[key] < 2.4, key
    assert fine["arrived"] < coarse["arrived"] / 3  # second order


def test_arrival_step_is_eq_11_with_the_remaining_time(puma):
    """One call: the hand rates J_hand qd are C7^T (b17(theta_f) - b17(theta)) / T and
    Omega alpha / T (eqs 11, 14-18), T = remaining, against fk and scipy; a remaining time
    below the minimum (zero, negative, or past the arrival) counts as the minimum; a NaN or
    infinite one is refused (status 1)."""
    target = target_pose(puma)
    rng = np.random.default_rng(11)
    worst = 0.0
    for remaining in (1.7, 0.3, 0.01, DT, 0.0, -0.5):
        q = QN + rng.uniform(-0.2, 0.2, 6)
        qd, error, scale, w, cond = puma.arrival_step(q, target, remaining)
        pose = puma.fk(q)
        dp = target[:3, 3] - pose[:3, 3]
        rotation = rotation_vector(pose[:3, :3].T @ target[:3, :3])
        T = max(remaining, DT)
        expected = np.r_[pose[:3, :3].T @ dp, rotation] / T
        rates = puma.jacobian_hand(q) @ qd
        free = np.linalg.solve(puma.jacobian_hand(q), expected)
        s = 1 / max(1, np.max(np.abs(free) / LIMITS))
        worst = max(worst, np.abs(rates - s * expected).max() / np.abs(expected).max())
        np.testing.assert_allclose(error, np.r_[dp, rotation], atol=1e-12)
        np.testing.assert_allclose(scale[0], s, rtol=1e-12)
        print(f"\nremaining {remaining:+g} s: T {T:g} s, rate_scale {scale[0]:.4g}")
    print(f"|J_hand qd - rate_scale S| / |S| at most {worst:.2e}")
    assert worst < 1e-12
    for bad in (np.nan, np.inf):  # a checked step: status 1 on a non-finite input
        with pytest.raises(FloatingPointError, match="status 1"):
            puma.arrival_step(QN, target, bad)


def test_rate_limits_make_the_arrival_late_and_rate_scale_says_so(puma):
    """The same move in T = 0.2 s asks joint rates beyond the limits from the start: the whole
    rate vector is scaled (rate_scale < 1), so the hand keeps to the line but falls behind;
    re-planned, it asks for more, and after T it finishes at the limits (remaining held at
    one period)."""
    T = 0.2
    _, arrival = approach_paths(puma, QN, target_pose(puma), T, DT, duration=0.5)
    m = path_measures(puma, arrival.q, arrival.t, 0.5)
    left = np.maximum(arrival.distance(), arrival.distance(slice(3, 6)))
    at_T = int(round(T / DT))
    arrived = arrival.t[np.flatnonzero(left > 1e-6).max() + 1]
    ratio = (np.abs(np.diff(arrival.q, axis=0)) / DT / LIMITS).max()
    limited = arrival.rate_scale < 1
    print(
        f"\ntarget in {T} s: rate_scale min {arrival.rate_scale.min():.3f} on {limited.sum()} of "
        f"{len(limited)} calls, |qd_i| / limit_i at most {ratio:.12f}; {arrival.distance()[at_T] * 1e3:.1f} mm "
        f"left at T, arrived (within 1e-6 m and rad) at {arrived:.3f} s; off the line {m['off_line']:.2e} m"
    )
    assert limited[0] and arrival.rate_scale.min() < 0.5 and ratio <= 1 + 1e-12
    assert arrival.distance()[at_T] > 0.01 and T < arrived < 0.5
    assert np.all(arrival.rate_scale[~limited] == 1)
    assert m["off_line"] < 1e-4  # scaled as a whole, the hand's direction is kept


def test_info_lists_the_arrival(puma):
    info = puma.info()
    print(f"\n{info['rate_control']['arrival']}")
    assert "arrival_step" in info["functions"] and "position_step" in info["functions"]
    assert info["rate_control"]["arrival"] == {"minimum_remaining": DT}
    assert info["rate_control"]["horizon"] == HORIZON


# -- a composite robot --------------------------------------------------------------------------
def test_composite_arrival_moves_the_box_on_a_straight_line(tmp_path):
    """styx_redundant's hand (three-link fingers, internal motions) under resolved_rate with
    `arrival`: the box pose (x, y, psi) moves on the straight line in those coordinates at
    constant speed and arrives at T = 1 s; the fingertips stay on the box (to the Euler
    step's drift, first order in dt)."""
    settings = {"horizon": 0.25, "arrival": {"minimum_remaining": DT}}
    g = Graphs(variant(tmp_path, "styx_redundant", "styx_rr_arrival", "hand", settings))
    theta0 = np.array(yaml.safe_load((SPECS / "styx_redundant.yaml").read_text())["simulation"]["theta0"])
    x0 = g.plant_position(theta0)
    move = np.array([0.02, 0.015, 0.3])
    T = 1.0
    exponential, arrival = approach_paths(g, theta0, x0 + move, T, DT)
    x = np.array([g.plant_position(th) for th in arrival.q])
    schedule = np.abs(x - x0 - np.outer(arrival.t / T, move)).max()
    along = (x - x0) @ move / (move @ move)
    off = np.abs(x - x0 - np.outer(along, move)).max()
    grasp = max(np.abs(h_inverse(xi) - g.fingers_read(th, np.zeros(6))[0]).max() for xi, th in zip(x, arrival.q))
    short = np.abs(exponential.error[-1]).max() / np.abs(move).max()
    print(
        f"\nbox {x0} -> {x[-1]} (target {x0 + move}): |x - target| at T {np.abs(x[-1] - x0 - move).max():.2e}; "
        f"off the line {off:.2e}, off the schedule x0 + (t/T) move {schedule:.2e}; fingertips off the box "
        f"{grasp:.2e} m; min rate_scale {arrival.rate_scale.min()}; exponential (horizon 0.25 s) short by "
        f"{short:.5f} of the move (exp(-4) = {np.exp(-4):.5f})"
    )
    assert np.abs(x[-1] - x0 - move).max() < 1e-6
    assert off < 1e-5 and schedule < 0.02 * DT and grasp < 0.02 * DT
    assert arrival.rate_scale.min() == 1
    assert abs(short / np.exp(-T / 0.25) - 1) < 2 * T * DT / (2 * 0.25**2)
    np.testing.assert_allclose(arrival.error[0], move, atol=1e-12)


# -- the spec layer ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "settings, message",
    [
        ("arrival: {minimum_remaining: 0}", "minimum_remaining: 0 is less than or equal to the minimum of 0"),
        ("arrival: {minimum_remaining: -1e-3}", "minimum_remaining: -0.001 is less than or equal to the minimum of 0"),
        ("arrival: {period: 1e-3}", "arrival.period: unknown key (allowed: minimum_remaining)"),
    ],
)
def test_located_errors(tmp_path, settings, message):
    leaf = PUMA_RMRC.read_text().split("  arm:\n    define:\n")[1]
    spec = write_spec(tmp_path, "bad", leaf, "        " + settings)
    line = spec.read_text().splitlines().index("        " + settings) + 1
    with pytest.raises(UserErrors) as error:
        load_system(str(spec))
    text = str(error.value)
    print(f"\n{text}")
    assert message in text and f"{spec}:{line}:" in text


def test_composite_summary_and_plain_specs_have_no_arrival(tmp_path):
    with_arrival = load_system(str(variant(tmp_path, "styx_high_ct", "styx_rr_a", "hand", {"arrival": {}})))
    plain = load_system(str(PUMA_RMRC))
    summary = with_arrival.root_node.rate.summary()
    print(f"\n{summary}")
    assert summary["arrival"] == {"minimum_remaining": 0.001}
    assert plain.root_node.rate.arrival is None and "arrival" not in plain.root_node.rate.summary()
