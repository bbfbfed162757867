"""The arms the peers are measured on, and the one model every side builds from each.

robotgen builds `URDF --tip TIP` (its locked joints held at 0: the Panda's fingers); the peers
read a copy of the URDF in which those joints are fixed, which is the same rigid-body model.
URDF <dynamics damping> is viscous friction in robotgen's inverse and forward dynamics and in
neither peer: the agreement check (harness.reference) takes it out of robotgen's outputs.
"""

from __future__ import annotations

import importlib.util
import site
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# name: (collection, file in it, tip link). The UR5 and the Panda as bench/run.py builds them;
# the KUKA iiwa from pybullet_data (example-robot-data 6.0.0 has none): its seven joints, tip link 7.
ARMS = {
    "ur5": ("example-robot-data", "ur_description/urdf/ur5_robot.urdf", "tool0"),
    "panda": ("example-robot-data", "panda_description/urdf/panda.urdf", "panda_hand_tcp"),
    "iiwa": ("pybullet_data", "kuka_iiwa/model.urdf", "lbr_iiwa_link_7"),
}


class ArmError(Exception):
    """An arm cannot be built here (its robot files are not installed, robotgen refuses it)."""


def collection(name: str) -> Path:
    if name == "pybullet_data":
        try:
            import pybullet_data
        except ImportError:
            raise ArmError("pybullet_data is not installed (pip install pybullet)") from None
        return Path(pybullet_data.getDataPath())
    for sp in site.getsitepackages() + [site.getusersitepackages()]:
        d = Path(sp) / "cmeel.prefix/share/example-robot-data/robots"
        if d.is_dir():
            return d
    raise ArmError("example-robot-data is not installed (pip install example-robot-data)")


@dataclass
class Arm:
    name: str
    urdf: Path  # the robot file robotgen reads
    tip: str
    out: Path  # robotgen's build
    module: object  # its Python extension
    nq: int
    locked: list[str]
    damping: list[float]  # viscous friction per joint (URDF <dynamics damping>)
    model_urdf: Path  # the copy the peers read: locked joints fixed

    @property
    def label(self) -> str:
        return f"{self.urdf.parent.parent.name}/{self.urdf.parent.name}/{self.urdf.name}"


def build(name: str, work: Path) -> Arm:
    """robotgen's build of arm NAME in WORK/NAME, its module imported, and the peers' URDF."""
    from robotgen.cli import main as robotgen_main

    where, rel, tip = ARMS[name]
    urdf = collection(where) / rel
    if not urdf.is_file():
        raise ArmError(f"{urdf} not found")
    out = work / name
    status = robotgen_main(["build", str(urdf), "--tip", tip, "--name", name, "-o", str(out)])
    if status != 0:
        raise ArmError(f"robotgen build {urdf} --tip {tip} failed with exit status {status}")
    module = load_module(name, out)
    node = module.info()["nodes"][name]
    for joint in node["joints"]:
        if joint["coulomb"] or joint["armature"]:
            raise ArmError(
                f"{name}: joint {joint['name']} has Coulomb friction or armature, which the "
                "peers' models do not have and the agreement check does not take out"
            )
    locked = list(node.get("locked_joints", []))
    model_urdf = work / f"{name}.urdf"
    model_urdf.write_text(with_fixed_joints(urdf.read_text(), locked))
    return Arm(
        name, urdf, tip, out, module, int(module.nq), locked, [float(j["viscous"]) for j in node["joints"]], model_urdf
    )


def load_module(name: str, out: Path):
    """The extension module in OUT, loaded from its file (not one of the same name imported before)."""
    path = next(out.glob(f"{name}.*.so"), None) or next(out.glob(f"{name}.*.pyd"), None)
    if path is None:
        raise ArmError(f"robotgen's build in {out} has no extension module")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def with_fixed_joints(text: str, locked: list[str]) -> str:
    """The URDF with each joint named in LOCKED made fixed (held at 0, as robotgen locks it)."""
    tree = ET.ElementTree(ET.fromstring(text))
    for joint in tree.getroot().iter("joint"):
        if joint.get("name") in locked:
            joint.set("type", "fixed")
            for child in list(joint):
                if child.tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
                    joint.remove(child)
    return ET.tostring(tree.getroot(), encoding="unicode")
