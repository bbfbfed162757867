"""Where the independent references' robot files live, and how to build them with robotgen."""

from __future__ import annotations

import importlib
import site
import sys
from pathlib import Path

from robotgen.cli import main


def robots_dir() -> Path:
    """example-robot-data ships only model files, under site-packages/cmeel.prefix/."""
    for sp in site.getsitepackages() + [site.getusersitepackages()]:
        d = Path(sp) / "cmeel.prefix/share/example-robot-data/robots"
        if d.is_dir():
            return d
    raise FileNotFoundError("example-robot-data is not installed (pip install example-robot-data)")


UR5 = ("ur_description/urdf/ur5_robot.urdf", "tool0")
PANDA = ("panda_description/urdf/panda.urdf", "panda_hand_tcp")


def build_urdf(urdf: Path, tip: str, name: str, out: Path):
    """robotgen build URDF --tip TIP --name NAME -o OUT, then import the module."""
    status = main(["build", str(urdf), "--tip", tip, "--name", name, "-o", str(out)])
    assert status == 0, f"robotgen build {urdf} exited with {status}"
    sys.path.insert(0, str(out))
    try:
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(out))
