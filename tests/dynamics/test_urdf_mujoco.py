"""The UR5 against MuJoCo: M and the bias forces qfrc_bias (C qd + gravity).

What had to be matched: MuJoCo loads the URDF with <visual>/<collision> removed (no mesh
files needed, and no geom-derived inertia), armature 0 (robotgen's URDF model has none),
and damping does not enter qfrc_bias (MuJoCo keeps it in qfrc_passive), so robotgen's
damping term is subtracted; MuJoCo's fusestatic merges the fixed links as robotgen does."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest
from robots import UR5, build_urdf, robots_dir


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    path = robots_dir() / UR5[0]
    module = build_urdf(path, UR5[1], "ur5_mj", tmp_path_factory.mktemp("ur5_mj"))
    text = path.read_text()
    text = re.sub(r"<(visual|collision)>.*?</\1>", "", text, flags=re.S)
    model = mujoco.MjModel.from_xml_string(text)
    model.opt.gravity[:] = [0, 0, -9.81]
    assert model.nv == module.nq
    assert np.all(model.dof_armature == 0)
    return module, model


def test_mass_and_bias_forces(ur5):
    module, model = ur5
    data = mujoco.MjData(model)
    rng = np.random.default_rng(11)
    damping = np.array([j["damping"] for j in next(iter(module.info()["nodes"].values()))["joints"]])
    worst_M = worst_b = 0.0
    for _ in range(200):
        q, qd = rng.uniform(-np.pi, np.pi, model.nq), rng.normal(size=model.nv)
        data.qpos[:], data.qvel[:] = q, qd
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        worst_M = max(worst_M, np.abs(module.mass(q) - M).max() / np.abs(M).max())
        bias = module.nonlinear(q, qd) - damping * qd
        worst_b = max(worst_b, np.abs(bias - data.qfrc_bias).max() / max(1, np.abs(data.qfrc_bias).max()))
    print(f"mujoco: M {worst_M:.1e}, bias {worst_b:.1e}")
    assert worst_M < 1e-9 and worst_b < 1e-9
