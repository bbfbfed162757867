"""Rate groups of a robot tree (robotgen.model.rate_groups, robotgen.symbolic.rate_steps): the
spec's periods checked where they are wrong, the groups a tree falls into, and the group steps
against the fused servo_step: run at one period, slowest first with the holds passed at once,
they give servo_step's torques and next state to the last bit."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system
from robotgen.model.parameter_struct import runtime_parameters
from robotgen.model.rate_groups import partition, rate_groups
from robotgen.symbolic.kernel import ParameterSymbols
from robotgen.symbolic.rate_steps import rate_kernels
from robotgen.symbolic.system import SystemGraphs
from robotgen.symbolic.system_kernels import system_kernels

SPECS = Path(__file__).resolve().parents[2] / "specs"
MULTIRATE = (SPECS / "styx_multirate.yaml").read_text()
LOW = (SPECS / "styx_low_ct.yaml").read_text()


def load(tmp_path, text: str, name: str = "spec.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return load_system(str(path))


def errors(tmp_path, text: str) -> list[str]:
    with pytest.raises(UserErrors) as caught:
        load(tmp_path, text)
    return [str(e) for e in caught.value.errors]


def position(text: str, needle: str, occurrence: int = 0) -> tuple[int, int]:
    """1-based line and column of the value after ``needle``'s occurrence in ``text``."""
    at = [m.end() for m in re.finditer(re.escape(needle), text)][occurrence]
    line = text.count("\n", 0, at) + 1
    return line, at - text.rfind("\n", 0, at)


def test_the_multirate_hand_has_two_groups():
    system = load_system(str(SPECS / "styx_multirate.yaml"))
    groups = rate_groups(system)
    fast, slow = groups.groups
    assert (fast.period, slow.period) == (0.0005, 0.005) and (fast.ticks, slow.ticks) == (1, 10)
    assert fast.controllers == ("pd_left", "pd_right") and slow.controllers == ("ff", "ct_hand")  # ff inherits
    assert slow.reads_root and not fast.reads_root
    assert slow.writes == ("pd_left", "pd_right") == fast.reads and not slow.reads
    assert fast.drives == ("left", "right") and slow.drives == ()
    assert groups.frame_ticks == 10 and groups.due(0) == (1, 0) and groups.due(3) == (0,) and groups.due(20) == (1, 0)


def test_the_root_period_defaults_to_simulation_dt_and_a_single_rate_tree_is_one_group(tmp_path):
    system = load_system(str(SPECS / "styx_multilevel.yaml"))
    groups = rate_groups(system)
    assert len(groups.groups) == 1 and groups.groups[0].period == 0.001  # its simulation.dt
    text = MULTIRATE.replace("      period: 0.005              # 200 Hz; ff below takes it too\n", "")
    text = text.replace("simulation:\n", "simulation:\n  dt: 0.004\n")
    assert [g.period for g in rate_groups(load(tmp_path, text)).groups] == [0.0005, 0.004]
    no_section = text[: text.index("simulation:")]
    assert [g.period for g in rate_groups(load(tmp_path, no_section)).groups] == [0.0005, 0.001]


def test_controllers_below_an_attach_root_each_read_the_root_trajectory(tmp_path):
    text = LOW.replace("kv: 20, gains: folded}", "kv: 20, gains: folded, period: 0.002}", 1)
    groups = rate_groups(load(tmp_path, text))
    fast, slow = groups.groups
    assert fast.controllers == ("ct_right",) and slow.controllers == ("ct_left",) and slow.ticks == 2
    assert fast.reads_root and slow.reads_root and not groups.boundaries
    assert fast.drives == ("right",) and slow.drives == ("left",)


PERIOD_ERRORS = [
    (
        "not a multiple of the fastest",
        ("period: 0.005  ", "period: 0.0012  "),
        ("period: ", 2),
        "0.0012 s is not an integer multiple of the fastest period in the tree (0.0005 s of 'pd_left')",
    ),
    (
        "slower than the controller above",
        ("kv: 0.1, period: 0.0005}", "kv: 0.1, period: 0.01}"),
        ("period: ", 0),
        "0.01 s is longer than the period of 'ff' above it (0.005 s of 'ff', from 'ct_hand')",
    ),
    (
        "too many ticks",
        ("period: 0.005  ", "period: 6  "),
        ("period: ", 2),
        "6 s is 1.2e+04 times the fastest period in the tree (0.0005 s of 'pd_left'); a group may span at most "
        "10000 fastest periods",
    ),
    (
        "dt unused",
        ("simulation:\n", "simulation:\n  dt: 0.001\n"),
        ("simulation:\n  dt: ", 0),
        "0.001 s is not the fastest controller period (0.0005 s of 'pd_left')",
    ),
]


@pytest.mark.parametrize("edit, needle, message", [c[1:] for c in PERIOD_ERRORS], ids=[c[0] for c in PERIOD_ERRORS])
def test_a_period_that_does_not_fit_is_reported_where_it_is_set(tmp_path, edit, needle, message):
    """One message, at the period that breaks the rule (not also at those checked against it)."""
    text = MULTIRATE.replace(*edit, 1)
    found = errors(tmp_path, text)
    line, col = position(text, *needle)
    assert len(found) == 1, found
    where, said = found[0].split(": ", 1)
    assert where.endswith(f"spec.yaml:{line}:{col}") and message in said, found


def test_every_period_divides_the_slowest(tmp_path):
    """Fig 4.2's fingers at 2 and 3 ms (a PD loop at 1 ms under the left one) repeat only every 6 ms."""
    left = "control: {robot: left, law: computed_torque, kp: 100, kv: 20, gains: folded}"
    right = "control: {robot: right, law: computed_torque, kp: 100, kv: 20, gains: folded}"
    assert LOW.count(left) == LOW.count(right) == 1
    text = LOW.replace(
        left,
        "control: {robot: pd_left, law: computed_torque, kp: 100, kv: 20, period: 0.002}\n"
        "  pd_left:\n    control: {robot: left, law: pd, kp: 1, kv: 0.1, period: 0.001}",
    )
    text = text.replace(right, right[:-1] + ", period: 0.003}").replace("  dt: 0.001\n", "")
    found = errors(tmp_path, text)
    line, col = position(text, "kv: 20, period: ", 0)
    assert len(found) == 1 and found[0].endswith(
        f"spec.yaml:{line}:{col}: nodes.ct_left.control.period: 0.002 s does not divide the slowest period in the tree "
        "(0.003 s of 'ct_right'): the groups' ticks must line up once per slowest period"
    ), found
    fits = text.replace("period: 0.003}", "period: 0.004}")
    assert [g.ticks for g in rate_groups(load(tmp_path, fits)).groups] == [1, 2, 4]


def test_a_period_under_a_root_law_is_refused(tmp_path):
    text = (SPECS / "puma560_rmac.yaml").read_text()
    text = text.replace("    control:\n", "    control:\n      period: 0.001\n", 1)
    found = errors(tmp_path, text)
    assert len(found) == 1 and "takes no period here (its settings go under resolved_adaptive)" in found[0], found


def test_a_period_that_is_no_positive_number_is_refused(tmp_path):
    for value, words in (
        ("0", "less than or equal to the minimum of 0"),
        ("-0.001", "is less than or equal to"),
        ("'1/0'", ""),
    ):
        found = errors(tmp_path, MULTIRATE.replace("period: 0.005  ", f"period: {value}  ", 1))
        assert len(found) == 1 and "nodes.ct_hand.control.period" in found[0] and words in found[0], found


def _servo_vs_groups(system, group_of: dict[str, int], period: float, seed: int):
    """The fused servo_step at ``period`` and the group steps of ``group_of`` (every group at
    ``period``) composed as the MultiRateController composes them at a tick where all run."""
    n_groups = max(group_of.values()) + 1
    groups = partition(system, group_of, (period,) * n_groups)
    parameters = ParameterSymbols.of(runtime_parameters(system))
    kernels = {k.name: k for k in rate_kernels(SystemGraphs(system, parameters), groups)}
    fused = {k.name: k for k in system_kernels(system)}
    rng = np.random.default_rng(seed)
    theta = np.array(fused["plant_inverse"].function([0.0, 0.12, 0.0])).ravel() + 0.01 * rng.standard_normal(4)
    values = {
        "theta": theta,
        "theta_dot": rng.standard_normal(4),
        "x_e": [0, 0.12, 0] + 0.01 * rng.standard_normal(3),
        "xd_e": rng.standard_normal(3),
        "xdd_e": rng.standard_normal(3),
        "f_e": rng.standard_normal(3),
        "f_i": [1.0],
        "tau_sensed": rng.standard_normal(4),
        "dt": period,
        "params": np.array([v for p in parameters.parameters for v in np.ravel(p.default)]) * (1 + 0.1 * seed),
    }
    state = np.array(fused["servo_init"].function(values["theta"], values["theta_dot"])).ravel()
    values["state"] = state + 1e-3 * rng.standard_normal(state.size)
    step = fused["servo_step"]
    out = dict(zip([p.name for p in step.outputs], step.function.call([values[p.name] for p in step.inputs])))
    tau, next_state, held = np.zeros(4), {}, {}
    offset = 0
    for group in reversed(groups.groups):  # the slowest first
        kernel = kernels[f"servo_step_g{group.index}"]
        given = {**values, **held}
        if any(p.name == "state" for p in kernel.inputs):
            size = next(p.size for p in kernel.inputs if p.name == "state")
            given["state"] = values["state"][offset : offset + size]
        result = dict(
            zip([p.name for p in kernel.outputs], kernel.function.call([given[p.name] for p in kernel.inputs]))
        )
        tau += np.array(result.pop("tau")).ravel()
        if "state_next" in result:
            next_state[group.index] = np.array(result.pop("state_next")).ravel()
            offset += next_state[group.index].size
        held.update(result)
    return np.array(out["tau"]).ravel(), np.array(out["state_next"]).ravel(), tau, next_state, groups


@pytest.mark.parametrize("seed", [0, 1])
def test_group_steps_at_one_period_are_the_fused_servo_step(tmp_path, seed):
    """Fig 4.3 cut between the PD loops and the levels above (the trajectories ff writes held
    and passed at once), and with ct_hand closing a loop on the sensed squeeze (tau_sensed)."""
    text = (
        (SPECS / "styx_multilevel.yaml").read_text().replace("      kv: 20\n", "      kv: 20\n      kf_internal: 0.5\n")
    )
    for system in (load_system(str(SPECS / "styx_multilevel.yaml")), load(tmp_path, text)):
        # state order: the walk's (ff before ct_hand), which is also the slow group's own order
        tau, state, tau_groups, states, groups = _servo_vs_groups(
            system, {"pd_left": 0, "pd_right": 0, "ff": 1, "ct_hand": 1}, 0.001, seed
        )
        assert groups.boundaries == ("pd_left", "pd_right")
        assert np.array_equal(tau, tau_groups), (tau, tau_groups)
        assert np.array_equal(state, states[1])
        assert np.abs(tau).max() > 1e-3  # a real torque, not zeros on both sides


def test_group_steps_under_an_attach_root_are_the_fused_servo_step():
    system = load_system(str(SPECS / "styx_low_ct.yaml"))
    tau, state, tau_groups, states, _ = _servo_vs_groups(system, {"ct_left": 1, "ct_right": 0}, 0.001, 2)
    assert np.array_equal(tau, tau_groups) and np.abs(tau).max() > 1e-3
    assert np.array_equal(state, np.concatenate([states[1], states[0]]))  # ct_left's state, then ct_right's


def test_a_group_step_folds_its_own_period():
    """servo_step_g1 of the multi-rate hand integrates its expected trajectories over its own
    5 ms: its next state is servo_step's at dt = 0.005."""
    system = load_system(str(SPECS / "styx_multirate.yaml"))
    kernels = {k.name: k for k in system_kernels(system)}
    g1, fused = kernels["servo_step_g1"], kernels["servo_step"]
    assert "dt" not in [p.name for p in g1.inputs]
    rng = np.random.default_rng(3)
    values = {
        "theta": np.array(kernels["plant_inverse"].function([0.0, 0.12, 0.0])).ravel(),
        "theta_dot": rng.standard_normal(4),
        "x_e": [0.001, 0.12, 0.01],
        "xd_e": rng.standard_normal(3),
        "xdd_e": rng.standard_normal(3),
        "f_e": np.zeros(3),
        "f_i": [1.0],
        "dt": 0.005,
        "params": [2, 0.1, 2, 0.1, 100, 20],
    }
    values["state"] = np.array(kernels["servo_init"].function(values["theta"], values["theta_dot"])).ravel()
    out_g1 = g1.function.call([values[p.name] for p in g1.inputs])
    out = fused.function.call([values[p.name] for p in fused.inputs])
    assert np.array_equal(np.array(out_g1[-1]), np.array(out[-1]))
    assert not np.any(np.array(out_g1[0]))  # its leaves are driven by the PD loops below it
