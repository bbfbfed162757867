"""The hand laws' modules offer the hand pose they control (hand_pose: the tip frame times the
law's tool) and how far a desired pose is from it (hand_distance), and their controllers
refuse, on the first step after a reset, a pose_d farther from the hand than START_DISTANCE
or START_ANGLE (status 3 in C, nothing written; a ValueError in Python) instead of
commanding the torques that close such a gap at once."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robotgen.model.laws.hand import START_ANGLE, START_DISTANCE

ROOT = Path(__file__).resolve().parents[2]
RMAC = ROOT / "specs" / "puma560_rmac.yaml"
Q0 = np.array([0, np.pi / 4, np.pi, 0, np.pi / 4, 0])  # the spec's start pose
ZERO = np.zeros(6)


@pytest.fixture(scope="module")
def rac_path(tmp_path_factory) -> Path:
    text = RMAC.read_text().replace("resolved_adaptive", "resolved_acceleration")
    path = tmp_path_factory.mktemp("start") / "puma560_rac_start.yaml"
    path.write_text(text.replace("name: puma560_rmac", "name: puma560_rac_start"))
    return path


@pytest.fixture(scope="module")
def modules(build_module, rac_path):
    return {"AdaptiveController": build_module(RMAC), "ResolvedAccelerationController": build_module(rac_path)}


def moved(pose: np.ndarray, shift=(0.0, 0.0, 0.0), turn=(0.0, 0.0, 0.0)) -> np.ndarray:
    """pose shifted by ``shift`` and turned by the rotation vector ``turn`` (base frame)."""
    out = pose.copy()
    out[:3, 3] += shift
    out[:3, :3] = Rotation.from_rotvec(turn).as_matrix() @ pose[:3, :3]
    return out


@pytest.mark.parametrize("cls", ["AdaptiveController", "ResolvedAccelerationController"])
def test_hand_pose_is_the_tip_times_the_tool(modules, cls):
    arm = modules[cls]
    tool = np.array(arm.info()["hand_control"]["tool"])
    assert not np.allclose(tool, np.eye(4))  # the spec's tool frame is not the tip
    rng = np.random.default_rng(0)
    for q in [Q0, *rng.uniform(-np.pi, np.pi, size=(20, 6))]:
        np.testing.assert_allclose(arm.hand_pose(q), arm.fk(q) @ tool, rtol=0, atol=1e-14)
    np.testing.assert_allclose(arm.hand_pose(rng.normal(size=(5, 6)))[:, 3], np.tile([0, 0, 0, 1.0], (5, 1)))


def test_hand_distance_against_numpy(modules):
    arm = modules["AdaptiveController"]
    rng = np.random.default_rng(1)
    for angle in [0.0, 1e-7, 0.3, 2.0, np.pi - 1e-6, np.pi]:
        q = rng.uniform(-2, 2, size=6)
        axis = rng.normal(size=3)
        shift = rng.normal(size=3) * 0.1
        pose_d = moved(arm.hand_pose(q), shift, angle * axis / np.linalg.norm(axis))
        distance, turned = arm.hand_distance(q, pose_d)
        assert distance == pytest.approx(np.linalg.norm(shift), rel=1e-12, abs=1e-15)
        assert turned == pytest.approx(angle, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize("cls", ["AdaptiveController", "ResolvedAccelerationController"])
def test_a_far_pose_d_on_the_first_step_is_refused(modules, cls):
    arm = modules[cls]
    c = getattr(arm, cls)()
    hand = arm.hand_pose(Q0)
    far = [
        moved(hand, (2 * START_DISTANCE, 0, 0)),
        moved(hand, turn=(0, 0, 2 * START_ANGLE)),
        arm.fk(Q0),
    ]  # the last: the tool frame left out
    for pose_d in far:
        with pytest.raises(ValueError) as caught:
            c.step(Q0, ZERO, pose_d, ZERO, ZERO)
        assert str(caught.value).startswith(f"{cls}.step(): on the first step after a reset, pose_d is ")
        assert "from the hand (at most 0.01 m and 0.05 rad): start the desired path at hand_pose(q)" in str(
            caught.value
        )
        assert not c.state.any() and c.last == {}  # nothing written: still reset
    assert "pose_d is 0.02 m and 0 rad from the hand" in _message(c, far[0])
    assert "pose_d is 0.1 m and 1.57 rad from the hand" in _message(c, far[2])
    near = moved(hand, (0.5 * START_DISTANCE, 0, 0), (0, 0.5 * START_ANGLE, 0))
    tau = c.step(Q0, ZERO, near, ZERO, ZERO)
    assert np.all(np.isfinite(tau))
    c.step(Q0, ZERO, far[0], ZERO, ZERO)  # not the first step: the law's own business
    c.reset()
    with pytest.raises(ValueError):
        c.step(Q0, ZERO, far[0], ZERO, ZERO)


def _message(c, pose_d) -> str:
    with pytest.raises(ValueError) as caught:
        c.step(Q0, ZERO, pose_d, ZERO, ZERO)
    return str(caught.value)


def test_the_adaptive_law_turns_a_start_error_into_large_torques(modules):
    """Why the check is there: the first step's torques grow by tens of N m per mm of start error."""
    arm = modules["AdaptiveController"]
    c = arm.AdaptiveController()
    hand = arm.hand_pose(Q0)
    held = c.step(Q0, ZERO, hand, ZERO, ZERO)
    c.reset()
    off = c.step(Q0, ZERO, moved(hand, (1e-3, 0, 0)), ZERO, ZERO)
    assert np.abs(off - held).max() > 50  # N m for 1 mm


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is required")
def test_the_c_step_returns_3_and_writes_nothing(modules, tmp_path):
    arm = modules["AdaptiveController"]
    out = Path(arm.__file__).parent
    name = arm.__name__
    hand = arm.hand_pose(Q0)
    far = moved(hand, (0, 2 * START_DISTANCE, 0))

    def array(values) -> str:
        return "{" + ", ".join(repr(float(v)) for v in np.ravel(values)) + "}"

    harness = tmp_path / "start.c"
    harness.write_text(f"""#include <stdio.h>
#include "{name}.h"
int main(void) {{
    const double q[6] = {array(Q0)}, zero[6] = {{0}}, far[16] = {array(far)}, hand[16] = {array(hand)};
    double tau[6] = {{7, 7, 7, 7, 7, 7}};
    {name}_params params = {name.upper()}_PARAMS_DEFAULT;
    {name}_adaptive_controller c;
    {name}_adaptive_controller_reset(&c);
    int refused = {name}_adaptive_controller_step(&c, q, zero, far, zero, zero, &params, tau);
    int untouched = tau[0] == 7 && c.initialised == 0 && c.state[0] == 0;
    int ok = {name}_adaptive_controller_step(&c, q, zero, hand, zero, zero, &params, tau);
    printf("%d %d %d %d\\n", refused, untouched, ok, c.initialised);
    return 0;
}}
""")
    exe = tmp_path / "start"
    subprocess.run(
        [
            "gcc",
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
    assert subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split() == ["3", "1", "0", "1"]
