"""The command line's promises (CONTRACT.md): exit statuses, FILE:LINE:COL messages with no
traceback, no output directory on failure, schema and info output."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from jsonschema import Draft202012Validator
from ruamel.yaml import YAML

from robotgen.cli import main

ROOT = Path(__file__).resolve().parent.parent
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
