"""The command line's promises (docs/cli.md): exit statuses, FILE:LINE:COL messages with no
traceback, no output directory on failure, schema and info output."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from jsonschema import Draft202012Validator
from ruamel.yaml import YAML

from robotgen.cli import main

ROOT = Path(__file__).resolve().parents[2]
PUMA = ROOT / "specs" / "puma560.yaml"

BAD = """robotgen: 1
name: bad
root: arm
nodes:
  arm:
    define:
      chain:
        convention: dh_standard
        joints:
          - type: revolute
            dh: {a: 1}
            link: {mass: -2}
"""


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robotgen", *args], capture_output=True, text=True, cwd=ROOT)


def test_bad_spec_exits_1_with_location_and_no_output(tmp_path):
    spec = tmp_path / "bad.yaml"
    spec.write_text(BAD)
    out = tmp_path / "out"
    result = run_cli("build", str(spec), "-o", str(out))
    assert result.returncode == 1
    assert result.stderr.startswith(f"{spec}:12:26: "), result.stderr
    assert "mass" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


def test_check_accepts_every_example_and_rejects_bad(tmp_path):
    for spec in sorted((ROOT / "specs").glob("*.yaml")):
        assert main(["check", str(spec)]) == 0, spec
    spec = tmp_path / "bad.yaml"
    spec.write_text(BAD)
    assert main(["check", str(spec)]) == 1


def test_usage_errors_exit_2():
    assert run_cli().returncode == 2
    assert run_cli("build").returncode == 2
    assert run_cli("build", str(PUMA), "--precision", "quad").returncode == 2


def test_schema_is_json_schema_that_accepts_the_examples():
    result = run_cli("schema")
    assert result.returncode == 0
    schema = json.loads(result.stdout)
    Draft202012Validator.check_schema(schema)
    validator = Draft202012Validator(schema)
    for spec in sorted((ROOT / "specs").glob("*.yaml")):
        data = json.loads(json.dumps(YAML(typ="safe").load(spec.read_text())))
        assert not list(validator.iter_errors(data)), spec


def test_info_prints_the_tree():
    result = run_cli("info", str(PUMA))
    assert result.returncode == 0
    assert "arm: define chain, nq = 6" in result.stdout
    assert "q6: revolute, parent 4" in result.stdout


def test_module_info_names_the_spec(tmp_path, build_module):
    import hashlib

    module = build_module(ROOT / "specs" / "two_link.yaml")
    info = module.info()
    assert info["nq"] == module.nq == 2
    assert info["spec_sha256"] == hashlib.sha256((ROOT / "specs" / "two_link.yaml").read_bytes()).hexdigest()
    assert "mass" in info["functions"] and "forward_dynamics" in info["functions"]


def test_build_urdf_tree(tmp_path):
    """--tree keeps every movable joint below the base: iCub's 32 joints in one module."""
    from robots import robots_dir

    urdf = robots_dir() / "icub_description" / "robots" / "icub.urdf"
    out = tmp_path / "icub"
    assert main(["build", str(urdf), "--tree", "--name", "icub", "-o", str(out), "--no-compile"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["nq"] == 32
    assert main(["build", str(urdf), "-o", str(tmp_path / "x")]) == 2  # neither --tip nor --tree


def test_version():
    import robotgen

    result = run_cli("--version")
    assert result.returncode == 0
    assert result.stdout.startswith(f"robotgen {robotgen.__version__} (casadi 3.8.2")


def test_a_closed_pipe_ends_quietly():
    """`robotgen schema | head -1`: the reader has what it wanted; no traceback, status 0."""
    p = subprocess.Popen(
        [sys.executable, "-m", "robotgen", "schema"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT
    )
    first = p.stdout.readline()
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait() == 0 and first == b"{\n"
    assert err == "", err


def test_a_module_name_that_is_not_an_identifier_is_refused(tmp_path):
    from robots import UR5, robots_dir

    out = tmp_path / "ur5"
    result = run_cli("build", str(robots_dir() / UR5[0]), "--tip", UR5[1], "--name", "UR5", "-o", str(out))
    assert result.returncode == 2
    assert "--name 'UR5' is not a module name" in result.stderr and "try --name ur5" in result.stderr
    assert not out.exists()


def test_a_non_spec_file_is_quoted_one_line_at_most(tmp_path):
    text = "".join(f"user{k}:x:{k}:{k}::/home/user{k}:/bin/sh\n" for k in range(200))
    path = tmp_path / "passwd"
    path.write_text(text)
    result = run_cli("check", str(path))
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1 and len(result.stderr) < 200, result.stderr
    assert "a spec must be a YAML mapping, got the string 'user0:x:0:0::/home/user0:/bin/sh" in result.stderr


def test_progress_on_request_and_quiet(tmp_path):
    import os

    spec = ROOT / "specs" / "two_link.yaml"
    env = dict(os.environ, ROBOTGEN_PROGRESS="1")
    shown = subprocess.run(
        [sys.executable, "-m", "robotgen", "build", str(spec), "-o", str(tmp_path / "a")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
    )
    assert shown.returncode == 0
    stages = [line.split("] ", 1)[1] for line in shown.stderr.splitlines() if line.startswith("robotgen: [")]
    assert len(stages) == len(shown.stderr.splitlines())  # nothing but progress on stderr
    assert [s.split(" ", 1)[0] for s in stages[:3]] == ["reading", "building", "printing"]
    assert "printing 17 C functions" in stages[2] and stages[3] == "printing C: fk (1/17)"
    assert stages[-2] == "printing C: jacobian_derivative (17/17)" and stages[-1].startswith("compiling the extension")
    quiet = subprocess.run(
        [sys.executable, "-m", "robotgen", "build", "-q", str(spec), "-o", str(tmp_path / "b")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
    )
    assert quiet.returncode == 0 and quiet.stderr == ""
    assert "built two_link" in shown.stdout and "built two_link" in quiet.stdout  # results stay on stdout


def test_accepted_deviations_keep_a_build_quiet(tmp_path):
    """The PUMA's published inertias violate the triangle inequality; the spec accepts that
    per inertia, so its builds print nothing on stderr. Without `accept` it warns, and an
    `accept` that is not needed is itself a warning."""
    result = run_cli("check", str(PUMA))
    assert result.returncode == 0 and result.stderr == ""
    text = PUMA.read_text()
    without = tmp_path / "puma_without.yaml"
    without.write_text(text.replace(", accept: [triangle_inequality]", ""))
    result = run_cli("check", str(without))
    assert result.returncode == 0 and result.stderr.count("violate the triangle inequality") == 2
    assert "add 'accept: [triangle_inequality]'" in result.stderr
    needless = tmp_path / "puma_needless.yaml"
    needless.write_text(
        text.replace(
            "inertia: {ixx: 0.13, iyy: 0.524, izz: 0.539, ixy: 0, ixz: 0, iyz: 0}",
            "inertia: {ixx: 0.13, iyy: 0.524, izz: 0.539, ixy: 0, ixz: 0, iyz: 0, accept: [triangle_inequality]}",
        )
    )
    result = run_cli("check", str(needless))
    assert result.returncode == 0
    assert "satisfy the triangle inequality; 'triangle_inequality' is not needed" in result.stderr
    assert result.stderr.count("warning") == 1


def test_info_shows_units_and_locked_joints():
    result = run_cli("info", str(ROOT / "specs" / "tripod_grasp.yaml"))
    assert result.returncode == 0
    assert "coordinates: x [m], y [m], z [m], roll [rad], pitch [rad], yaw [rad]" in result.stdout
    assert "coordinates: x1 [m], y1 [m], z1 [m]" in result.stdout
    result = run_cli("info", str(PUMA))
    assert "coordinates: q1 [rad]," in result.stdout


def test_a_missing_compiler_is_the_machines_not_a_bug(tmp_path):
    import os

    out = tmp_path / "out"
    result = subprocess.run(
        [sys.executable, "-m", "robotgen", "build", str(PUMA), "-o", str(out)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=dict(os.environ, CC="no-such-cc"),
    )
    assert result.returncode == 1
    assert "no C compiler: cannot run 'no-such-cc'" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


def test_urdf_options_on_a_spec_are_refused():
    result = run_cli("build", str(PUMA), "--tip", "tool0")
    assert result.returncode == 2 and "--tip applies to a URDF file" in result.stderr
