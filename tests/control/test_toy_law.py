"""docs/ARCHITECTURE.md's "Adding a law" recipe followed with nothing else: one new module (its
symbolic law, its settings reader and its schema block) and one registry line, here put in
place for the test. The toy law is PD with its gains scaled by a factor read from its own
settings block; its servo step must equal PD's with the scaled gains, and its block is
checked like every law's (located messages, exit 1)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from robotgen.errors import UserErrors
from robotgen.frontend import load_system, schema_json
from robotgen.model.laws import registry
from robotgen.model.laws.descriptor import Law
from robotgen.symbolic import kernels_for

ROOT = Path(__file__).resolve().parents[2]

TOY_MODULE = '''
"""A toy law: PD whose gains are scaled by ``toy.scale``."""
import dataclasses

from robotgen.symbolic.control.law import Command, TreeLaw, Written


def write(c: Command) -> Written:
    return Written(c.F_d + c.feedback(c.position_error()), c.x_d, c.v_d, c.a_d)


LAW = TreeLaw("toy", transparent=False, write=write)

SCHEMA = {"type": "object", "additionalProperties": False, "required": ["scale"],
          "properties": {"scale": {"type": ["number", "string"], "description": "gain factor, > 0"}}}


def read(reader, system, node, spec, robot):
    path = ("nodes", node.name, "control")
    if "toy" not in spec:
        reader.at_key(path, "missing required key 'toy' (the settings of law toy)")
        return node
    scale = reader.constant(path + ("toy", "scale"), spec["toy"]["scale"], minimum=0.0, exclusive=True)
    return dataclasses.replace(node, kp=scale * node.kp, kv=scale * node.kv)
'''

SPEC = """\
robotgen: 1
name: {name}
root: servo
nodes:
  arm:
    define:
      chain:
        convention: dh_standard
        gravity: [0, -9.81, 0]
        joints:
          - {{name: shoulder, type: revolute, dh: {{a: 0.8, alpha: 0, d: 0, theta: 0}},
             link: {{mass: 1.2, com: [-0.45, 0, 0], inertia: {{ixx: 0.001, iyy: 0.07, izz: 0.07}}}}}}
          - {{name: elbow, type: revolute, dh: {{a: 0.6, alpha: 0, d: 0, theta: 0}},
             link: {{mass: 0.9, com: [-0.32, 0, 0], inertia: {{ixx: 0.0005, iyy: 0.03, izz: 0.03}}}}}}
  servo:
    control:
      robot: arm
      law: {law}
      gains: folded
      kp: {kp}
      kv: {kv}
{extra}"""


@pytest.fixture
def toy_law(tmp_path, monkeypatch):
    """The recipe: the law's module, and its line in the registry."""
    (tmp_path / "toy_law.py").write_text(TOY_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(
        registry.LAWS, "toy", Law("toy", "toy_law:LAW", settings="toy_law:read", schema="toy_law:SCHEMA")
    )


def spec(tmp_path: Path, name: str, law: str, kp, kv, extra: str = "") -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(SPEC.format(name=name, law=law, kp=kp, kv=kv, extra=textwrap.indent(extra, "      ")))
    return path


def servo_step(path: Path):
    return next(k for k in kernels_for(load_system(path)) if k.name == "servo_step").function


def test_a_toy_law_added_by_the_recipe_builds(tmp_path, toy_law):
    toy = servo_step(spec(tmp_path, "toy", "toy", 30, [4, 6], "toy:\n  scale: 2.5\n"))
    pd = servo_step(spec(tmp_path, "pd", "pd", 75, [10, 15]))
    assert toy.name_in() == pd.name_in()
    rng = np.random.default_rng(37)
    for _ in range(3):
        point = [rng.normal(size=toy.size1_in(i)) for i in range(toy.n_in())]
        assert np.allclose(np.array(toy(*point)[0]), np.array(pd(*point)[0]), rtol=1e-13, atol=1e-12)
    reference = servo_step(spec(tmp_path, "pd1", "pd", 30, [4, 6]))
    assert not np.allclose(np.array(toy(*point)[0]), np.array(reference(*point)[0]))  # the scale is read
    assert '"toy"' in schema_json() and "toy_law" not in schema_json()


@pytest.mark.parametrize(
    "extra, line, column, message",
    [
        ("toy:\n  scale: -1\n", 23, 16, "toy.scale: -1.0 is less than or equal to the minimum of 0"),
        ("toy:\n  scale: 1\n  offset: 2\n", 24, 9, "toy.offset: unknown key (allowed: scale)"),
        ("", 16, 5, "missing required key 'toy' (the settings of law toy)"),
        ("toy:\n  scale: 1\nresolved_rate: {}\n", 24, 7, "settings of law resolved_rate; this node's law is toy"),
    ],
)
def test_a_toy_laws_block_is_checked_where_it_is_written(tmp_path, toy_law, extra, line, column, message):
    path = spec(tmp_path, "toy", "toy", 30, 4, extra)
    with pytest.raises(UserErrors) as error:
        load_system(path)
    text = str(error.value)
    assert f"{path}:{line}:{column}:" in text and message in text, text


def test_without_its_registry_line_the_law_is_refused(tmp_path):
    path = spec(tmp_path, "toy", "toy", 30, 4, "toy:\n  scale: 1\n")
    r = subprocess.run([sys.executable, "-m", "robotgen", "check", str(path)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1 and f"{path}:18:12:" in r.stderr and "'toy' is not one of" in r.stderr, r.stderr
