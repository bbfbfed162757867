"""A user's first commands after a plain `pip install .` (no extras) into a fresh virtual
environment: every CLI command the README shows works, simulate included (its plots need
matplotlib, which is a dependency), and the documentation pages error hints name are there
(`robotgen docs`)."""

from __future__ import annotations

import subprocess
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_plain_install_runs_every_readme_command(tmp_path):
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    python = env_dir / "bin" / "python"
    install = subprocess.run(
        [str(python), "-m", "pip", "install", "--quiet", str(ROOT)], capture_output=True, text=True
    )
    assert install.returncode == 0, install.stdout + install.stderr
    robotgen = env_dir / "bin" / "robotgen"
    work = tmp_path / "work"
    work.mkdir()

    def start(*args: str) -> subprocess.Popen:
        return subprocess.Popen(
            [str(robotgen), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=work
        )

    def run(*args: str) -> subprocess.CompletedProcess:
        return finish(start(*args))

    def finish(process: subprocess.Popen) -> subprocess.CompletedProcess:
        stdout, stderr = process.communicate()
        return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)

    specs = ROOT / "specs"
    # the two long commands (a compile, a simulation) run side by side with the others
    building = start("build", str(specs / "puma560.yaml"))
    simulating = start("simulate", str(specs / "styx_high_ct.yaml"), "--duration", "0.2", "-o", "sim")

    listed = subprocess.run([str(python), "-m", "pip", "list", "--format=freeze"], capture_output=True, text=True)
    installed = {line.split("==")[0].lower() for line in listed.stdout.splitlines()}
    assert "pin" not in installed and "pytest" not in installed  # no extras came along

    assert run("--version").returncode == 0
    assert run("check", str(specs / "puma560.yaml")).returncode == 0
    assert "arm: define chain" in run("info", str(specs / "puma560.yaml")).stdout
    assert run("schema").stdout.startswith("{")
    listed = run("docs").stdout  # the pages came along, installed in the environment, not read from the clone
    assert listed.startswith(f"robotgen's documentation ({env_dir}") and "spec-format" in listed
    assert run("docs", "spec-format").stdout == (ROOT / "docs" / "spec-format.md").read_text()
    built, simulated = finish(building), finish(simulating)
    assert built.returncode == 0, built.stderr
    assert (work / "generated" / "puma560" / "puma560.h").is_file()
    probe = subprocess.run(
        [
            str(python),
            "-c",
            "import sys; sys.path.insert(0, 'generated/puma560'); "
            "import puma560, numpy as np; print(puma560.mass(np.zeros(6))[0, 0])",
        ],
        capture_output=True,
        text=True,
        cwd=work,
    )
    assert probe.returncode == 0 and float(probe.stdout) > 1.0, probe.stderr
    assert simulated.returncode == 0, simulated.stderr
    assert (work / "sim" / "styx_high_ct.csv").is_file()
    png = (work / "sim" / "styx_high_ct.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Traceback" not in simulated.stderr + built.stderr
