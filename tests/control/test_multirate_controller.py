"""The compiled MultiRateController of specs/styx_multirate.yaml (Fig 4.3 at 2 kHz and 200 Hz):
its torques are the group steps' composed by hand (what the slow group wrote held until its next
tick, the fast group on every tick), a failed step leaves it as it was; the lifted closed loop's
spectral radius against the error's growth in simulation, for a stable and an unstable choice of
the upper level's period; `robotgen simulate` and `robotgen info` on it."""

from __future__ import annotations

import dataclasses
import inspect
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robotgen.frontend import load_system
from robotgen.model.rate_groups import partition, rate_groups
from robotgen.simulation import tree as simulate
from robotgen.symbolic.lifted_loop import lifted_loop

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "specs" / "styx_multirate.yaml"


@pytest.fixture(scope="module")
def hand(build_module):
    return build_module(SPEC)


def _inputs(module, rng, k: int):
    theta = module.plant_inverse(np.array([0.0, 0.12, 0.0])) + 1e-3 * rng.standard_normal(4)
    return (
        theta,
        0.1 * rng.standard_normal(4),
        np.array([0.002 * k, 0.12, 0.01]),
        0.01 * rng.standard_normal(3),
        0.01 * rng.standard_normal(3),
        np.zeros(3),
        np.array([1.0]),
    )


def test_the_slow_groups_writes_are_held_between_its_ticks(hand):
    c, rng = hand.MultiRateController(), np.random.default_rng(0)
    assert c.periods == (0.0005, 0.005) and c.ticks == (1, 10) and c.tick == 0
    state = held = slow_tau = None
    for k in range(35):
        args = _inputs(hand, rng, k)
        tau = c.step(*args)
        if k == 0:
            state = hand.servo_init_g1(args[0], args[1])
        if k % 10 == 0:  # the slow group's tick: what it writes now is held for the next 10 ticks
            slow_tau, left, right, state = hand.servo_step_g1(*args, state)
            held = {"wr_pd_left": left, "wr_pd_right": right}
        fast_tau = hand.servo_step_g0(args[0], args[1], **held)
        np.testing.assert_array_equal(tau, fast_tau + slow_tau)
        np.testing.assert_array_equal(c.torques, [fast_tau, slow_tau])
        assert c.held.keys() == held.keys() and all(np.array_equal(c.held[n], held[n]) for n in held)
        np.testing.assert_array_equal(c.state[1], state)
        assert c.tick == (k + 1) % 10
    assert not np.any(slow_tau)  # the upper levels drive no leaf: their force reaches the PD loops held in F_d
    assert np.abs(tau).max() > 1e-3


def test_the_held_trajectory_is_what_ff_writes_to_the_pd_loops(hand):
    """wr_pd_left is [x_e; xd_e; xdd_e; F_e] in the left fingertip's coordinates: at rest on the
    start pose the expected fingertip is where the finger is, and the PD loop's torque is zero."""
    c = hand.MultiRateController()
    theta = hand.plant_inverse(np.array([0.0, 0.12, 0.0]))
    zero = np.zeros(3)
    tau = c.step(theta, np.zeros(4), np.array([0.0, 0.12, 0.0]), zero, zero, zero, np.array([0.0]))
    left = c.held["wr_pd_left"]
    np.testing.assert_allclose(left[:2], hand.pd_left_read(theta, np.zeros(4))[0], atol=1e-12)
    np.testing.assert_allclose(left[2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(tau, 0.0, atol=1e-12)


def test_a_failed_step_changes_nothing_and_reset_restarts(hand):
    c, rng = hand.MultiRateController(), np.random.default_rng(1)
    for k in range(13):
        c.step(*_inputs(hand, rng, k))
    before = (c.tick, c.held, c.state, c.torques)
    bad = list(_inputs(hand, rng, 13))
    bad[1] = np.array([np.nan, 0, 0, 0])
    with pytest.raises(FloatingPointError, match=r"MultiRateController.step\(\): an input is NaN"):
        c.step(*bad)
    assert c.tick == before[0] == 3 and np.array_equal(c.torques, before[3])
    assert all(np.array_equal(c.held[n], before[1][n]) for n in before[1]) and np.array_equal(c.state[1], before[2][1])
    c.reset()
    assert c.tick == 0 and not np.any(c.torques) and not np.any(c.state[1])
    args = _inputs(hand, rng, 0)
    fresh = hand.MultiRateController()
    np.testing.assert_array_equal(c.step(*args), fresh.step(*args))  # the init runs again


def test_run_time_parameters_reach_every_group(hand):
    rng = np.random.default_rng(2)
    args = [_inputs(hand, rng, k) for k in range(12)]
    soft = hand.MultiRateController(ct_hand_kp=40.0, pd_left_kp=1.0)
    default = hand.MultiRateController()
    for a in args:
        tau_soft, tau_default = soft.step(*a), default.step(*a)
    state = hand.servo_init_g1(args[0][0], args[0][1])
    _, left, right, _ = hand.servo_step_g1(
        *args[10], hand.servo_step_g1(*args[0], state, ct_hand_kp=40.0)[3], ct_hand_kp=40.0
    )
    fast = hand.servo_step_g0(args[11][0], args[11][1], left, right, ct_hand_kp=40.0, pd_left_kp=1.0)
    np.testing.assert_array_equal(tau_soft, fast)
    assert np.abs(tau_soft - tau_default).max() > 1e-6
    soft.parameters["pd_left_kp"] = 2.0
    assert soft.parameters["pd_left_kp"] == 2.0 and soft.parameters["ct_hand_kp"] == 40.0


def _variant(tmp_path, period: float, name: str, offset: float) -> Path:
    """The multi-rate hand with its upper level at ``period``, held at its start pose from an
    offset of ``offset`` m (10 times that in rad), small enough for the loop to stay linear
    and large enough to stay above the rounding for the whole run."""
    text = SPEC.read_text().replace("name: styx_multirate", f"name: {name}")
    text = text.replace("period: 0.005  ", f"period: {period}  ")
    text = re.sub(r"initial_error: .*", f"initial_error: [{offset}, {-offset}, {10 * offset}]", text)
    text = re.sub(r"amplitude: .*", "amplitude: [0, 0, 0]", text)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def _growth(module, system, frames: int, window: int, apart: int) -> float:
    """The error's growth per slowest period in simulation: the largest |x - x_d| over the
    last ``window`` periods against the same ``apart`` periods earlier, per period."""
    groups = rate_groups(system)
    settings = dataclasses.replace(system.simulation, dt=groups.base_period, duration=frames * groups.groups[-1].period)
    result = simulate.run(module, settings, multirate=True)
    e = np.abs(result.error[:: groups.frame_ticks]).max(axis=1)
    return (e[-window:].max() / e[-window - apart : -apart].max()) ** (1 / apart)


@pytest.mark.parametrize(
    "period, name, offset, frames, window, apart",
    [
        (0.005, "styx_rates_stable", 1e-4, 300, 80, 200),  # its slowest mode turns 0.083 rad per period: 76 a turn
        (0.1, "styx_rates_unstable", 1e-11, 40, 6, 30),  # 1.06 rad per period: 6 periods a turn
    ],
)
def test_the_lifted_spectral_radius_is_the_errors_growth_in_simulation(
    tmp_path, build_module, period, name, offset, frames, window, apart
):
    path = _variant(tmp_path, period, name, offset)
    system = load_system(str(path))
    loop = lifted_loop(system, rate_groups(system))
    growth = _growth(build_module(path), system, frames, window, apart)
    assert loop.frame == pytest.approx(period) and loop.ticks == round(period / 0.0005)
    assert (loop.spectral_radius < 1) == (period == 0.005) == (growth < 1), (loop.spectral_radius, growth)
    assert growth == pytest.approx(loop.spectral_radius, rel=0.01), (loop.spectral_radius, growth)


def test_the_lifted_loop_of_one_rate_is_the_single_rate_servo_steps():
    """The same tree with both levels in one 0.5 ms group: the lifted map over 10 ticks is the
    tenth power of one tick's, whose radius is that of the fused loop; and the Fig 4.3 hand at
    5 ms decays about as fast as at 0.5 ms (computed torque's double pole at -10/s: 0.951 per
    5 ms in continuous time)."""
    system = load_system(str(SPEC))
    one = lifted_loop(system, partition(system, dict.fromkeys(["pd_left", "pd_right", "ff", "ct_hand"], 0), (0.0005,)))
    two = lifted_loop(system, partition(system, {"pd_left": 0, "pd_right": 0, "ff": 1, "ct_hand": 1}, (0.0005, 0.0005)))
    assert two.spectral_radius == pytest.approx(one.spectral_radius, rel=1e-12)
    multi = lifted_loop(system, rate_groups(system))
    assert multi.spectral_radius == pytest.approx(one.spectral_radius**10, abs=0.01)
    assert 0.94 < multi.spectral_radius < 0.97
    slower = {
        period: lifted_loop(
            system, partition(system, {"pd_left": 0, "pd_right": 0, "ff": 1, "ct_hand": 1}, (0.0005, period))
        ).spectral_radius
        for period in (0.02, 0.1)
    }
    said = f"the radius is {slower[0.1]:.3f} (UNSTABLE, per 100 ms), at 0.02 s {slower[0.02]:.4f}"
    assert said in " ".join((ROOT / "docs" / "cli.md").read_text().split()), said


def _block(page: str, marker: str) -> str:
    """The body of the first fenced block after ``marker`` in docs/``page``."""
    text = (ROOT / "docs" / page).read_text()
    rest = text[text.index(marker) :]
    body = rest[rest.index("\n", rest.index("```")) + 1 :]
    return body[: body.index("```")]


def _output(page: str, command: str) -> list[str]:
    """The lines a console block of docs/``page`` shows after ``command``, to the block's end."""
    text = (ROOT / "docs" / page).read_text()
    rest = text[text.index(command) :]
    return rest[rest.index("\n") + 1 : rest.index("```")].splitlines()


def test_simulate_runs_both_and_reports_their_cost(tmp_path, hand):
    """The run cli.md shows, its figures as shown; each cost is operations times rate."""
    out = tmp_path / "sim"
    r = subprocess.run(
        [sys.executable, "-m", "robotgen", "simulate", str(SPEC), "-o", str(out), "-q"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stderr
    text = r.stdout
    shown = _output("cli.md", "$ robotgen simulate specs/styx_multirate.yaml")
    assert text.splitlines()[: len(shown) - 1] == shown[:-1], text  # the last names the files
    assert "simulated 3.000 s in 6000 steps of 0.0005 s on the robotgen plant" in text, text
    info = hand.info()["multirate"]
    rows = re.findall(r"multi-rate\s+(servo_step_g\d): +(\d+) x +([\d.]+) Hz = +(\d+)", text)
    assert [(step, int(ops), float(hz)) for step, ops, hz, _ in rows] == [
        (g["step"], g["operations"], 1 / g["period"]) for g in info["groups"]
    ]
    assert all(int(each) == int(ops) * float(hz) for _, ops, hz, each in rows)
    total = int(re.search(r"multi-rate\s+total: +(\d+)", text).group(1))
    single = int(re.search(r"single rate\s+servo_step: +\d+ x +2000 Hz = +(\d+)", text).group(1))
    assert total == sum(int(each) for *_, each in rows)
    assert single == info["single_rate_operations"] * 2000 and total < 0.2 * single
    ratio = float(re.search(r"costs ([\d.]+) of the single-rate one", text).group(1))
    assert ratio == pytest.approx(total / single, abs=5e-4)
    for stem in ("styx_multirate", "styx_multirate_single_rate"):
        assert (out / f"{stem}.csv").is_file() and (out / f"{stem}.png").is_file()
    multi = np.loadtxt(out / "styx_multirate.csv", delimiter=",", skiprows=1)
    single_run = np.loadtxt(out / "styx_multirate_single_rate.csv", delimiter=",", skiprows=1)
    assert multi.shape == single_run.shape == (6001, 1 + 3 + 3 + 4 + 1)
    tau = multi[:, 7:11]  # the ZOH of the 200 Hz level: the torque's steps fall every 10 ticks
    jumps = np.abs(np.diff(tau, axis=0)).max(axis=1)
    assert np.median(jumps[9::10]) > 3 * np.median(np.delete(jumps, np.s_[9::10]))
    for args, words in (
        (["--dt", "0.001"], "--dt applies to single-rate trees"),
        (["--plant", "both"], "choose --plant robotgen or --plant mujoco"),
    ):
        bad = subprocess.run(
            [sys.executable, "-m", "robotgen", "simulate", str(SPEC), *args, "-o", str(out), "-q"],
            capture_output=True,
            text=True,
            cwd=ROOT,
        )
        assert bad.returncode == 2 and words in bad.stderr, bad.stderr


def test_info_prints_the_groups_and_the_lifted_radius():
    r = subprocess.run([sys.executable, "-m", "robotgen", "info", str(SPEC)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    system = load_system(str(SPEC))
    radius = lifted_loop(system, rate_groups(system)).spectral_radius
    assert f"spectral radius {radius:.4f}, stable" in r.stdout, r.stdout
    shown = _output("cli.md", "$ robotgen info specs/styx_multirate.yaml")[1:]  # after "..."
    assert r.stdout.splitlines()[-len(shown) :] == shown, r.stdout


def test_info_says_why_a_start_off_the_grasp_is_not_linearised(tmp_path):
    """Without a simulation section the start is the rest posture, every finger angle 0: no grasp there."""
    path = tmp_path / "unposed.yaml"
    path.write_text(SPEC.read_text().split("simulation:")[0])
    r = subprocess.run([sys.executable, "-m", "robotgen", "info", str(path)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and r.stdout.splitlines()[-1] == (
        "  lifted closed loop: not linearised: the start pose, from the rest posture (no simulation.start or theta0), "
        "breaks a grasp (out of the inverse kinematics' reach); give simulation.start or theta0 on every grasp"
    ), r.stdout


def test_the_c_struct_and_the_python_class_agree_as_the_docs_say(tmp_path, hand):
    """c-api.md's program against the emitted C (under AddressSanitizer and UBSan where gcc has
    them), python-api.md's lines against the module: the same torques, as the pages print them."""
    import shutil

    source = _block("c-api.md", "A program that holds the box")
    (tmp_path / "multirate_app.c").write_text(source)
    out = Path(hand.__file__).parent
    sanitize = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"] if shutil.which("gcc") else []
    cc = "gcc" if sanitize else "cc"
    subprocess.run(
        [
            cc,
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            *sanitize,
            "-O1",
            str(tmp_path / "multirate_app.c"),
            f"-I{out}",
            str(out / "styx_multirate.c"),
            "-lm",
            "-o",
            str(tmp_path / "app"),
        ],
        check=True,
    )
    printed = subprocess.run([str(tmp_path / "app")], capture_output=True, text=True, check=True).stdout
    assert printed.splitlines() == _output("c-api.md", "$ ./multirate_app")
    c = hand.MultiRateController()
    theta, zero = hand.plant_inverse([0.0, 0.12, 0.0]), np.zeros(3)
    for _ in range(12):
        tau = c.step(theta, np.zeros(4), [0.01, 0.12, 0.0], zero, zero, zero, [1.0])
    assert printed == f"tick {c.tick}: tau = " + " ".join(f"{v:.5f}" for v in tau) + "\n"
    comment = f"# tau = {np.array2string(tau, precision=5)}, c.tick = {c.tick}"
    assert comment in (ROOT / "docs" / "python-api.md").read_text(), comment


def test_a_period_error_is_reported_as_spec_format_shows(tmp_path):
    shown = _block("spec-format.md", "refused, and so is `simulation.dt`").strip()
    path = tmp_path / "styx_multirate.yaml"
    path.write_text(SPEC.read_text().replace("kv: 0.1, period: 0.0005}", "kv: 0.1, period: 0.01}", 1))
    r = subprocess.run([sys.executable, "-m", "robotgen", "check", str(path)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1 and r.stderr.strip() == str(path) + shown[len("styx_multirate.yaml") :], r.stderr


def test_groups_below_an_attach_root_without_holds_or_state(tmp_path, build_module):
    """Fig 4.2's fingers under PD loops at 500 Hz and 1 kHz: both groups read the root trajectory,
    nothing is held, no group keeps a state; the torques are each group's last, summed."""
    left = "control: {robot: left, law: computed_torque, kp: 100, kv: 20, gains: folded}"
    right = "control: {robot: right, law: computed_torque, kp: 100, kv: 20, gains: folded}"
    text = (ROOT / "specs" / "styx_low_ct.yaml").read_text().replace("name: styx_low_ct", "name: styx_low_pd_rates")
    text = text.replace(left, "control: {robot: left, law: pd, kp: 1, kv: 0.1, period: 0.002}")
    text = text.replace(right, "control: {robot: right, law: pd, kp: 1, kv: 0.1}")
    path = tmp_path / "styx_low_pd_rates.yaml"
    path.write_text(text)
    m = build_module(path)
    c, rng = m.MultiRateController(), np.random.default_rng(4)
    assert c.ticks == (1, 2) and c.held == {} and c.state == {}
    assert m.info()["multirate"]["held"] == []
    slow = None
    for k in range(7):
        args = _inputs(m, rng, k)
        tau = c.step(*args)
        if k % 2 == 0:
            slow = m.servo_step_g1(*args)
        fast = m.servo_step_g0(*args)
        np.testing.assert_array_equal(tau, fast + slow)
        assert np.any(fast[2:]) and not np.any(fast[:2]) and np.any(slow[:2]) and not np.any(slow[2:])


@pytest.mark.parametrize("loop", ["kf_internal: 0.5", "kf_internal: 0.5\n      ki_internal: 20"])
def test_a_loop_on_the_sensed_squeeze_takes_tau_sensed(tmp_path, build_module, loop):
    """ct_hand with kf_internal (and ki_internal): the slow group reads the leaves' sensed forces
    at its ticks, and the controller takes them after f_i; the PI loop's integral is one more
    block of the slow group's state, integrated over the slow group's period."""
    integrates = "ki_internal" in loop
    name = "styx_rates_pi" if integrates else "styx_rates_squeeze"
    text = SPEC.read_text().replace("name: styx_multirate", f"name: {name}")
    text = text.replace("      period: 0.005  ", f"      {loop}\n      period: 0.005  ")
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    m = build_module(path)
    assert list(inspect.signature(m.MultiRateController.step).parameters)[-2:] == ["tau_sensed", "out"]
    n_fi = len(m.info()["nodes"][m.info()["root"]]["internal_forces"])
    assert m.servo_init_g1(np.zeros(m.nq), np.zeros(m.nq)).shape == (14 + n_fi * integrates,)
    c, rng = m.MultiRateController(), np.random.default_rng(5)
    for k in range(12):
        args = (*_inputs(m, rng, k), 0.1 * rng.standard_normal(4))
        tau = c.step(*args)
        if k == 0:
            state = m.servo_init_g1(args[0], args[1])
        if k % 10 == 0:
            before = state
            slow, left, right, state = m.servo_step_g1(*args, state)
            if integrates:  # z grows by the slow period times the error, whichever way it points
                assert np.all(np.abs(state[14:] - before[14:]) > 0)
                np.testing.assert_array_equal(c.state[1], state)
        np.testing.assert_array_equal(tau, m.servo_step_g0(args[0], args[1], left, right) + slow)
    unloaded, squeezed = (m.servo_step_g1(*args[:7], sensed, state)[1] for sensed in (np.zeros(4), np.ones(4)))
    # the squeeze loop changes the force written to the fingers (F_e), not their trajectory (x_e, xd_e, xdd_e)
    np.testing.assert_array_equal(unloaded[:6], squeezed[:6])
    assert np.abs(unloaded[6:] - squeezed[6:]).max() > 1e-5


def test_a_squeeze_integral_is_checked_at_its_own_groups_period(tmp_path):
    """ki_internal 300 with kf_internal 0.5 is stable at the 0.5 ms of the finger loops (ki dt =
    0.15 < 1) but not at ct_hand's 5 ms (1.5): the check uses the period the loop runs at."""
    text = SPEC.read_text().replace("name: styx_multirate", "name: styx_rates_ki")
    path = tmp_path / "styx_rates_ki.yaml"
    for ki, refused in ((300, True), (150, False)):
        loop = f"      kf_internal: 0.5\n      ki_internal: {ki}\n      period: 0.005  "
        path.write_text(text.replace("      period: 0.005  ", loop))
        r = subprocess.run(
            [sys.executable, "-m", "robotgen", "check", str(path)], capture_output=True, text=True, cwd=ROOT
        )
        assert (r.returncode == 1) == refused, r.stderr
        if refused:
            assert "ki_internal 300 with dt = 0.005 s" in r.stderr and "got 1.5" in r.stderr, r.stderr


@pytest.fixture(scope="module")
def open_integral(tmp_path_factory, build_module):
    """The multi-rate hand with its expected trajectories integrated as printed (anchor: false)."""
    text = SPEC.read_text().replace("name: styx_multirate", "name: styx_multirate_open")
    text = text.replace("law: feedforward}", "law: feedforward, anchor: false}")
    text = text.replace("      period: 0.005  ", "      anchor: false\n      period: 0.005  ")
    path = tmp_path_factory.mktemp("open") / "styx_multirate_open.yaml"
    path.write_text(text)
    system = load_system(str(path))
    assert [system.nodes[n].anchor for n in ("ff", "ct_hand")] == [None, None]
    return build_module(path)


def _long_run(module, duration: float):
    system = load_system(str(SPEC))
    settings = dataclasses.replace(system.simulation, dt=0.0005, duration=duration)
    r = simulate.run(module, settings, multirate=True)
    return r, r.f_actual[:, 0] - r.f_commanded[0]


def test_the_multi_rate_hand_holds_its_squeeze_and_its_track_for_40_s(hand, open_integral):
    """The reference repeats every 20 s (0.5, 0.25, 0.3 Hz): over 40 s, the second period's errors
    are the first's (the anchored expected trajectories drift nowhere), the squeeze stays within
    2% of its 1 N and psi within 3e-4 rad of the reference once settled. As printed (anchor:
    false) ff's expected fingertips drift apart and the squeeze is lost: past 0.1 N off by 20 s."""
    r, f = _long_run(hand, 40.0)
    psi = np.abs(r.error[:, 2])
    first, second = (r.t > 2) & (r.t <= 20), r.t > 22
    assert np.abs(f[r.t > 1]).max() < 0.02, np.abs(f[r.t > 1]).max()
    assert psi[first].max() < 3e-4 and psi[second].max() < 3e-4, (psi[first].max(), psi[second].max())
    assert psi[second].max() == pytest.approx(psi[first].max(), rel=0.05)
    assert np.abs(f[second]).max() == pytest.approx(np.abs(f[first]).max(), rel=0.05)
    open_run, open_f = _long_run(open_integral, 20.0)
    assert abs(open_f[-1]) > 0.1 and abs(open_f[-1]) > 5 * np.abs(f[r.t <= 20]).max(), open_f[-1]
