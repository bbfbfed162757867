"""`robotgen simulate --plant mujoco`: MuJoCo as an independent plant (robotgen/simulation/mujoco).

Without contacts the two plants integrate the same ODE by the same classical RK4 step (MuJoCo's
RK4 at the servo period, the torque held): only the floating-point rounding of M, C, N differs
(~1e-16 relative), and the closed loops contract, so the trajectories agree to rounding. The
tolerance 1e-12 leaves three orders of magnitude over what was measured (4e-16 rad on the PUMA
under computed torque, 3e-16 m on the adaptive hand); a different integrator shows up at once
(ten MuJoCo steps per period differ by robotgen's own RK4 truncation error, ~1e-6 rad).

With contacts (the Styx hands) the grasp is unilateral and frictional: the demo specs' squeeze
must keep every contact closed and inside its friction cone, and none loses the box."""

from __future__ import annotations

import csv
import dataclasses
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from reference import const

from robotgen.cli import main
from robotgen.errors import MUJOCO_INSTALL, UserError
from robotgen.frontend import load_system
from robotgen.simulation import hand as hand_simulation
from robotgen.simulation import tree as simulate
from robotgen.simulation.mujoco.model import plant_model
from robotgen.simulation.mujoco.run import MujocoPlant, TreePlant, check_agreement, root_payload, tree_plant

ROOT = Path(__file__).resolve().parents[2]
SPECS = ROOT / "specs"
PUMA_CT, RMAC, HIGH = SPECS / "puma560_ct.yaml", SPECS / "puma560_rmac.yaml", SPECS / "styx_high_ct.yaml"
STYX = [SPECS / f"styx_{kind}.yaml" for kind in ("high_ct", "low_ct", "multilevel", "redundant")]
ROUNDING = 1e-12  # same ODE, same RK4 step: the plants differ by rounding only (module docstring)


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robotgen", *args], capture_output=True, text=True, cwd=ROOT)


def variant(tmp_path: Path, base: Path, name: str, change) -> Path:
    data = yaml.safe_load(base.read_text())
    data["name"] = name
    change(data)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def both_plants(module, system, **changes):
    s = dataclasses.replace(system.simulation, **changes)
    _, make = tree_plant(system, module, s.dt)
    return simulate.run(module, s), simulate.run(module, s, plant=make)


@pytest.fixture(scope="module")
def puma(build_module):
    return load_system(str(PUMA_CT)), build_module(PUMA_CT)


def test_written_mjcf_loads_back_with_robotgens_mass_matrix(puma, tmp_path):
    """The MJCF simulate writes beside the CSV, loaded from the file: armature and damping are
    the spec's motor inertia times gear ratio squared and viscous friction (read from the YAML
    here), and mj_fullM is robotgen's M (armature included) at random states."""
    system, module = puma
    out = tmp_path / "sim"
    assert main(["simulate", str(PUMA_CT), "--plant", "mujoco", "--duration", "0.05", "-o", str(out), "-q"]) == 0
    model = mujoco.MjModel.from_xml_path(str(out / "puma560_ct.xml"))
    joints = yaml.safe_load(PUMA_CT.read_text())["nodes"]["arm"]["define"]["chain"]["joints"]
    armature = [const(j["motor"]["inertia"]) * const(j["motor"]["gear_ratio"]) ** 2 for j in joints]
    np.testing.assert_allclose(model.dof_armature, armature, rtol=1e-14)
    np.testing.assert_allclose(model.dof_damping, [const(j["friction"]["viscous"]) for j in joints], rtol=1e-14)
    data = mujoco.MjData(model)
    M = np.zeros((model.nv, model.nv))
    worst = 0.0
    for q in np.random.default_rng(3).uniform(-np.pi, np.pi, (50, model.nq)):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, M)
        worst = max(worst, float(np.abs(M - module.arm_mass(q)).max() / np.abs(M).max()))
    print(f"\n  PUMA 560: |mj_fullM - M| / |M| <= {worst:.2e} at 50 random q")
    assert worst < 1e-10


def test_styx_mechanism_is_the_fingers_point_masses(build_module):
    """The formulas fingers' mechanism in MuJoCo, mapped to absolute angles (theta = T q,
    T = [[1, 0], [1, 1]]): T^-T mj_fullM T^-1 equals the closed form of two point masses
    M11 = (m1 + m2) l^2, M12 = m2 l^2 cos(th1 - th2), M22 = m2 l^2 (the spec's numbers)."""
    system = load_system(str(HIGH))
    model = mujoco.MjModel.from_xml_string(plant_model(system, 1e-3).xml)
    p = yaml.safe_load(HIGH.read_text())["nodes"]["left"]["define"]["formulas"]["parameters"]
    m1, m2, l = p["m1"], p["m2"], p["l1"]
    T_inv = np.linalg.inv(np.array([[1.0, 0.0], [1.0, 1.0]]))
    data, M = mujoco.MjData(model), np.zeros((model.nv, model.nv))
    worst = 0.0
    for th in np.random.default_rng(4).uniform(-np.pi, np.pi, (20, 2)):
        data.qpos[:2] = T_inv @ th
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, M)
        mapped = T_inv.T @ M[:2, :2] @ T_inv
        c = np.cos(th[0] - th[1])
        closed = np.array([[(m1 + m2) * l * l, m2 * l * l * c], [m2 * l * l * c, m2 * l * l]])
        worst = max(worst, float(np.abs(mapped - closed).max() / np.abs(closed).max()))
    print(f"\n  Styx finger: mechanism against the closed form, {worst:.1e} relative")
    assert worst < 1e-10  # the compiler's 1e-14 bound on the point masses' moments: ~1e-11


def test_computed_torque_puma_tracks_alike_on_both_plants(puma):
    """2 s at 1 kHz of computed torque with gravity, armature, viscous and smoothed Coulomb
    friction: the joint trajectories agree to rounding. Ten MuJoCo RK4 steps per period
    integrate the held torque more finely, and differ by robotgen's RK4 truncation error."""
    system, module = puma
    robotgen_run, mujoco_run = both_plants(module, system)
    assert mujoco_run.plant == "mujoco" and mujoco_run.t[-1] == pytest.approx(2.0)
    gap = np.abs(robotgen_run.x - mujoco_run.x).max()
    assert np.ptp(mujoco_run.x, axis=0).max() > 1e-2  # it moved (the error at t = 0 would hold without motion)
    print(f"\n  PUMA computed torque, 2 s: |q_robotgen - q_mujoco| <= {gap:.1e} rad")
    assert gap < ROUNDING
    plant = plant_model(system, system.simulation.dt)
    fine = dataclasses.replace(
        plant, xml=plant.xml.replace('timestep="0.001"', 'timestep="0.0001"'), substeps=10, timestep=1e-4
    )
    finer = simulate.run(
        module, system.simulation, plant=lambda m, th, thd, v, n: TreePlant(MujocoPlant(fine), m, th, thd, n, None)
    )
    truncation = np.abs(robotgen_run.x - finer.x).max()
    print(f"  ten MuJoCo steps per period: {truncation:.2e} rad (robotgen's RK4 at 1 ms)")
    assert 1e-9 < truncation < 1e-5


def test_adaptive_hand_agrees_on_both_plants(build_module):
    """The adaptive PUMA (a hand law) for 2 s, 2 kg picked up at 1 s: MuJoCo's hand holds the
    payload in a body welded to the last link, robotgen's adds it to the link; the hand paths
    agree to rounding, adapting and frozen."""
    system, module = load_system(str(RMAC)), build_module(RMAC)
    s = dataclasses.replace(system.simulation, duration=2.0)
    runs = {
        p: hand_simulation.run(module, system, s, keys=("adaptive", "frozen"), plant=p) for p in ("robotgen", "mujoco")
    }
    for a, b in zip(runs["robotgen"].runs, runs["mujoco"].runs):
        gap = np.abs(a.p - b.p).max()
        print(
            f"\n  {a.label}: |p_robotgen - p_mujoco| <= {gap:.1e} m, RMS after the pickup "
            f"{1e3 * a.rms(runs['robotgen'].window(1.0)):.4f} / {1e3 * b.rms(runs['mujoco'].window(1.0)):.4f} mm"
        )
        assert gap < ROUNDING
        assert a.rms(runs["robotgen"].window(1.0)) > 10 * a.rms(runs["robotgen"].before)  # the payload was felt
    assert '<body name="hand_payload"' in runs["mujoco"].mjcf


def test_regulator_runs_on_both_plants(tmp_path):
    """The resolved-rate PUMA's lqr_step (torques) against both plants, side by side."""
    out = tmp_path / "sim"
    r = run_cli("simulate", "specs/puma560_rmrc.yaml", "--plant", "both", "--duration", "0.5", "-o", str(out), "-q")
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("the plants agree to"))
    assert float(line.split()[4]) < ROUNDING, line
    for name in ("puma560_rmrc.csv", "puma560_rmrc_mujoco.csv", "puma560_rmrc.xml", "puma560_rmrc_mujoco.png"):
        assert (out / name).is_file()
    rows = np.array(list(csv.reader(open(out / "puma560_rmrc_mujoco.csv")))[1:], float)
    theta0 = [const(v) for v in yaml.safe_load((SPECS / "puma560_rmrc.yaml").read_text())["simulation"]["theta0"]]
    np.testing.assert_allclose(rows[0, 1:7], theta0, rtol=0, atol=1e-9)  # x_q1..q6 start at theta0 (10 digits)


@pytest.mark.parametrize("spec", STYX, ids=[s.stem for s in STYX])
def test_styx_demo_grasp_holds_on_mujocos_contacts(spec, build_module):
    """The 1990 paper's hands on MuJoCo's contacts for the whole demo path: every contact
    closed after the squeeze is established and inside its friction cone, every fingertip on
    its pad, the squeeze carried as commanded, and the box where robotgen's rigid grasp puts it
    within the contacts' compliance and the fingertip spheres' rolling."""
    system, module = load_system(str(spec)), build_module(spec)
    robotgen_run, mujoco_run = both_plants(module, system)
    c = mujoco_run.contacts
    usage = c.worst_usage()
    print(
        f"\n  {spec.stem}: max |f_t|/(mu f_n) {np.round(usage, 4)}, slip {np.round(1e3 * c.largest_slip(), 3)} mm, "
        f"|x_robotgen - x_mujoco| {np.abs(robotgen_run.x - mujoco_run.x).max(axis=0)}"
    )
    assert c.holds and c.first_loss is None
    assert np.all(usage < 0.2)
    assert np.all(c.array("normal")[c.settled()] > 0.5)  # each tip presses with about 1/sqrt(2) N
    settled = mujoco_run.t > 0.05
    assert np.abs(mujoco_run.f_actual[settled] - 1.0).max() < 0.05
    gap = np.abs(robotgen_run.x - mujoco_run.x).max(axis=0)
    assert np.all(gap[:2] < 2e-5) and gap[2] < 5e-4


def test_the_multi_level_hand_holds_the_box_for_20_s_on_mujocos_contacts(build_module):
    """Fig 4.3's hand for 20 s (the demo's 3 s, and then two periods of the slowest reference
    component, 0.25 Hz): every contact stays closed and inside its cone, the squeeze stays within
    5% of its 1 N, and the box's true pose (MuJoCo's body) stays within what the fingertips'
    rolling explains of the pose the fingers sense, no further off in the last 8 s than in the
    8 s before: nothing creeps."""
    spec = SPECS / "styx_multilevel.yaml"
    system, module = load_system(str(spec)), build_module(spec)
    s = dataclasses.replace(system.simulation, duration=20.0)
    run = simulate.run(module, s, plant=tree_plant(system, module, s.dt)[1])
    c = run.contacts
    assert c.holds and c.first_loss is None and np.all(c.worst_usage() < 0.2)
    assert np.abs(run.f_actual[run.t > 0.05] - 1.0).max() < 0.05
    gap = np.abs(run.payload_pose - run.x)
    early, late = gap[(run.t > 4) & (run.t <= 12)].max(axis=0), gap[run.t > 12].max(axis=0)
    print(f"\n  styx_multilevel, 20 s on MuJoCo: |true pose - sensed pose| 4-12 s {early}, 12-20 s {late}")
    assert np.all(gap[:, :2] < 5e-4) and np.all(gap[:, 2] < 1e-2)
    assert np.all(late <= 1.5 * early)


def test_tripod_holds_its_box_up_by_friction(build_module):
    """The spatial grasp: a free box (MuJoCo's free joint) held at three points by friction
    alone against its weight. Every contact closes and stays inside its cone, the three squeezes
    are carried as commanded (robotgen's H: the pair squeezes orthonormalised), and the sensed
    pose follows robotgen's plant."""
    spec = SPECS / "tripod_grasp.yaml"
    system, module = load_system(str(spec)), build_module(spec)
    robotgen_run, mujoco_run = both_plants(module, system)
    c = mujoco_run.contacts
    assert c.holds and np.all(c.worst_usage() < 0.6)
    assert c.array("normal")[c.settled()].sum(axis=1).min() > 9.81  # friction carries the weight
    settled = mujoco_run.t > 0.05
    np.testing.assert_allclose(mujoco_run.f_actual[settled], 10.0, rtol=5e-3)
    gap = np.abs(robotgen_run.x - mujoco_run.x).max(axis=0)
    print(
        f"\n  tripod: max |f_t|/(mu f_n) {np.round(c.worst_usage(), 3)}, slid "
        f"{np.round(1e3 * c.array('sliding')[-1], 4)} mm, |x_robotgen - x_mujoco| {gap}"
    )
    assert np.all(gap[:3] < 5e-5) and np.all(gap[3:] < 2e-3)
    assert np.all(c.array("sliding")[-1] < 5e-5)  # the noslip solver: no creep under the weight


def test_too_little_squeeze_loses_the_box(build_module):
    """No squeeze: the fingertip that must pull to accelerate the box cannot, the contacts open
    and the box leaves the fingertips; with the demo's squeeze it stays (above)."""
    system, module = load_system(str(HIGH)), build_module(HIGH)
    s = dataclasses.replace(system.simulation, duration=0.5, internal_forces=(0.0,))
    _, make = tree_plant(system, module, s.dt)
    run = simulate.run(module, s, plant=make)
    loss = run.contacts.first_loss
    assert loss is not None and loss[0] < 0.5
    assert np.nanmax(run.contacts.worst_usage()) == pytest.approx(1.0, abs=1e-6)  # sliding before it went
    assert "LOST" in simulate.summary(run)
    print(f"\n  no squeeze: lost at t = {loss[0]:.3f} s ({run.contacts.contacts[loss[1]].name})")


def test_sensed_forces_close_the_squeeze_loop(tmp_path, build_module):
    """kf_internal on the hand's controller: the servo step takes the leaves' sensed forces
    (rd's force term), and its squeeze error shrinks by 1 / (1 + kf) on both plants, as
    f = f_d + kf (f_d - f_sensed) with the force sensed a period late predicts. robotgen's own
    plant_sensed_forces are the fingertip forces: H J^-T tau_sensed is the squeeze the
    grasp carries and J^-T tau_sensed sums to the box's mass times its acceleration."""
    kf = 0.5
    spec = variant(tmp_path, HIGH, "styx_kf", lambda d: d["nodes"]["ct_hand"]["control"].update(kf_internal=kf))
    closed, open_loop = build_module(spec), build_module(HIGH)
    assert "tau_sensed" in closed.servo_step.__doc__ and "tau_sensed" not in open_loop.servo_step.__doc__
    l, m_box = 0.1, 0.2
    rng = np.random.default_rng(5)
    for _ in range(5):
        theta = closed.plant_inverse(np.array([0.0, 0.12, 0.0]) + rng.uniform(-0.01, 0.01, 3))
        v, tau = rng.normal(size=3) * 0.1, rng.normal(size=4) * 0.05
        sensed = closed.plant_sensed_forces(theta, v, tau)
        tips = []
        for a, b, s in ((theta[0], theta[1], sensed[:2]), (theta[2], theta[3], sensed[2:])):
            J = np.array([[-l * np.sin(a), -l * np.sin(b)], [l * np.cos(a), l * np.cos(b)]])
            tips.append(np.linalg.solve(J.T, s))
        psi = closed.plant_position(theta)[2]
        u = np.array([np.cos(psi), np.sin(psi)])
        np.testing.assert_allclose(
            (u @ tips[0] - u @ tips[1]) / np.sqrt(2), closed.plant_internal_forces(theta, v, tau), rtol=1e-10
        )
        np.testing.assert_allclose(tips[0] + tips[1], m_box * closed.plant_dynamics(theta, v, tau)[1][:2], rtol=1e-9)
    system_closed, system_open = load_system(str(spec)), load_system(str(HIGH))
    ratios = {}
    for plant in ("robotgen", "mujoco"):
        errors = []
        for system, module in ((system_open, open_loop), (system_closed, closed)):
            s = dataclasses.replace(system.simulation, duration=1.5)
            run = (
                simulate.run(module, s)
                if plant == "robotgen"
                else simulate.run(module, s, plant=tree_plant(system, module, s.dt)[1])
            )
            settled = run.t > 0.05
            errors.append(np.sqrt(np.mean((run.f_actual[settled, 0] - 1.0) ** 2)))
        ratios[plant] = errors[1] / errors[0]
    print(f"\n  squeeze error with kf_internal = {kf} over without: {ratios} (1 / (1 + kf) = {1 / (1 + kf):.4f})")
    for ratio in ratios.values():
        assert ratio == pytest.approx(1 / (1 + kf), rel=0.05)


def test_kf_internal_is_checked(tmp_path):
    spec = variant(tmp_path, HIGH, "styx_kf_high", lambda d: d["nodes"]["ct_hand"]["control"].update(kf_internal=1.5))
    r = run_cli("check", str(spec))
    assert r.returncode == 1 and "kf_internal 1.5 must be below 1" in r.stderr and "pole at -kf" in r.stderr
    spec = variant(tmp_path, PUMA_CT, "puma_kf", lambda d: d["nodes"]["ct"]["control"].update(kf_internal=0.5))
    r = run_cli("check", str(spec))
    assert r.returncode == 1 and "robot 'arm' has no internal forces to close a loop on" in r.stderr


def test_plant_flag_and_spec_setting(tmp_path):
    """simulation.plant: both writes each plant's CSV and PNG and the MJCF; --plant overrides."""

    def both(data):
        data["simulation"].update(plant="both", duration=0.2)

    spec = variant(tmp_path, HIGH, "styx_both", both)
    out = tmp_path / "sim"
    r = run_cli("simulate", str(spec), "-o", str(out), "-q")
    assert r.returncode == 0, r.stderr
    assert "on both plants" in r.stdout and "grasp hand on MuJoCo's contacts" in r.stdout
    header = next(csv.reader(open(out / "styx_both_mujoco.csv")))
    assert header[-10:] == [f"{k}_hand.c{i}" for k in ("fn", "ft", "usage", "slip", "gap") for i in (1, 2)]
    assert "xtrue_psi" in header and "fn_hand.c1" not in next(csv.reader(open(out / "styx_both.csv")))
    model = mujoco.MjModel.from_xml_path(str(out / "styx_both.xml"))
    assert model.npair == 2 and list(model.pair_friction[:, 0]) == [1.0, 1.0]
    assert (out / "styx_both_mujoco.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out2 = tmp_path / "sim2"
    r = run_cli("simulate", str(spec), "-o", str(out2), "--plant", "robotgen", "-q")
    assert r.returncode == 0 and "on the robotgen plant" in r.stdout
    # and the record of what simulate wrote (robotgen.output_files)
    assert sorted(p.name for p in out2.iterdir()) == [".robotgen-files", "styx_both.csv", "styx_both.png"]
    r = run_cli("simulate", str(spec), "--plant", "bullet")
    assert r.returncode == 2 and "invalid choice: 'bullet'" in r.stderr


def test_missing_mujoco_gives_the_install_hint(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco raises ImportError
    assert main(["simulate", str(HIGH), "--plant", "mujoco", "-o", str(tmp_path / "a"), "-q"]) == 1
    err = capsys.readouterr().err
    assert MUJOCO_INSTALL in err and "Traceback" not in err
    spec = variant(tmp_path, HIGH, "styx_mj_spec", lambda d: d["simulation"].update(plant="mujoco"))
    assert main(["simulate", str(spec), "-o", str(tmp_path / "b"), "-q"]) == 1
    err = capsys.readouterr().err
    line = spec.read_text().splitlines().index("  plant: mujoco") + 1
    assert err.startswith(f"{spec}:{line}:") and "simulation.plant" in err and MUJOCO_INSTALL in err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_what_mujoco_cannot_model_is_a_located_error(tmp_path, build_module):
    """A formulas leaf without a mechanism (a tripod gantry's taken out), a mechanism that is not the
    formulas' (a wrong mass), and coordinates that are not affine in the joints."""
    bare = variant(
        tmp_path,
        SPECS / "tripod_grasp.yaml",
        "tripod_bare",
        lambda d: d["nodes"]["f1"]["define"]["formulas"].pop("mechanism"),
    )
    r = run_cli("simulate", str(bare), "--plant", "mujoco", "-o", str(tmp_path / "t"))
    line = bare.read_text().splitlines().index("  f1:") + 1
    assert r.returncode == 1 and r.stderr.startswith(f"{bare}:{line}:3: ") and "needs a mechanism" in r.stderr, r.stderr

    def heavy(data):
        data["nodes"]["left"]["define"]["formulas"]["mechanism"]["joints"][1]["link"]["mass"] = 0.25

    spec = variant(tmp_path, HIGH, "styx_heavy", heavy)
    system, module = load_system(str(spec)), build_module(spec)
    theta = module.plant_inverse(np.array([0.0, 0.12, 0.0]))
    _, make = tree_plant(system, module, 1e-3)
    with pytest.raises(UserError) as e:
        make(module, theta, np.zeros(4), np.zeros(3), 3)
    where = spec.read_text().splitlines().index("        mechanism:") + 1
    assert e.value.location.line == where and "does not reproduce robotgen's: M differs" in e.value.message

    def sine(data):
        data["nodes"]["left"]["define"]["formulas"]["mechanism"]["coordinates"] = ["la1", "sin(la1) + la2"]

    r = run_cli("check", str(variant(tmp_path, HIGH, "styx_sine", sine)))
    assert r.returncode == 1 and "must be affine in the joint positions la1, la2" in r.stderr


def test_agreement_check_sees_a_wrong_fingertip(build_module):
    """check_agreement compares each MuJoCo fingertip with the grasp's robots' rd: a tool frame
    1 mm off is refused at the mechanism."""
    system, module = load_system(str(HIGH)), build_module(HIGH)
    plant = plant_model(system, 1e-3)
    moved = dataclasses.replace(
        plant,
        xml=plant.xml.replace(
            '<site name="left/tip" size="0.0005" pos="0.1 0.0 0.0"',
            '<site name="left/tip" size="0.0005" pos="0.101 0.0 0.0"',
        ),
    )
    theta = module.plant_inverse(np.array([0.0, 0.12, 0.0]))
    robots = system.nodes["hand"].robots

    def tips(th):
        y = np.concatenate([getattr(module, f"{r}_read")(th, np.zeros(4))[0] for r in robots])
        return [("left", y[:2]), ("right", y[2:])]

    def leaf_dynamics(th, thd):
        return [
            (
                getattr(module, f"{n}_mass")(th),
                getattr(module, f"{n}_coriolis")(th, thd) @ thd[s] + getattr(module, f"{n}_n")(th, thd),
            )
            for n, s in (("left", slice(0, 2)), ("right", slice(2, 4)))
        ]

    check_agreement(MujocoPlant(plant), leaf_dynamics, theta, np.random.default_rng(0), tips)
    with pytest.raises(UserError, match="puts the fingertip of leaf 'left' at"):
        check_agreement(MujocoPlant(moved), leaf_dynamics, theta, np.random.default_rng(0), tips)
    assert root_payload(system) == "box"
