"""Every URDF of example-robot-data (and of pybullet_data when pybullet is installed), read by
robotgen as a tree and as a chain to its deepest link, and read by Pinocchio.

- ``read(file)``: what each reader makes of the file (a refusal and its reason, or the
  system robotgen builds) — fast, no graphs;
- ``compare(system, file)``: M, gravity, inverse dynamics (with the URDF's damping and
  friction), C and the tip Jacobian of the built system's kernels (the CasADi functions the C
  is printed from) against Pinocchio's model of the same file with the same joints locked,
  and with each mimic joint at multiplier * its leader + offset, projected on the leaders'
  coordinates (Pinocchio reads <mimic> as an ordinary joint);
- ``tables(reads)``: the Markdown tables of docs/robots.md (every refusal with its reason),
  so that ``python tests/urdf_sweep.py --write`` regenerates them and a test checks that
  they are current.

The deepest link, the joints each build must have and the base are found here from the XML
alone (expat, none of robotgen's code), so that a reader choosing the wrong joints fails.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from robots import robots_dir  # noqa: E402

from robotgen.errors import UserError  # noqa: E402
from robotgen.frontend.urdf import load_urdf_system, load_urdf_tree_system  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent / "docs" / "robots.md"
MOVABLE = ("revolute", "continuous", "prismatic")
N_STATES = 10
TOL = 1e-9


def pybullet_dir() -> Path | None:
    try:
        import pybullet_data
    except ImportError:
        return None
    return Path(pybullet_data.getDataPath())


def sources() -> dict[str, Path]:
    """The collections swept: name -> directory (pybullet_data only when installed)."""
    found = {"example-robot-data": robots_dir()}
    if (pb := pybullet_dir()) is not None:
        found["pybullet_data"] = pb
    return found


def files(source: str) -> list[Path]:
    return sorted(sources()[source].rglob("*.urdf"))


# --- the file's structure, independently of robotgen ------------------------------------------


@dataclass
class Structure:
    """Joints by child link: (name, type, parent link, its <mimic> as (leader, multiplier,
    offset) or None), links in file order."""

    links: list[str] = field(default_factory=list)
    joints: dict[str, tuple[str, str, str, tuple[str, float, float] | None]] = field(default_factory=dict)

    def root(self) -> str:
        return next(l for l in self.links if l not in self.joints)

    def path(self, link: str) -> list[tuple[str, str, str, bool]]:
        """The joints from the root down to ``link``."""
        out = []
        while link in self.joints:
            out.append(self.joints[link])
            link = self.joints[link][2]
        return out[::-1]

    def deepest(self) -> str | None:
        """The link with the most movable joints above it whose path has no mimic joint, the
        first in file order among equals; None without any."""
        best, most = None, 0
        for link in self.links:
            path = self.path(link)
            if any(mimic for _, _, _, mimic in path):
                continue
            count = sum(kind in MOVABLE for _, kind, _, _ in path)
            if count > most:
                best, most = link, count
        return best

    def tree_joints(self) -> set[str]:
        return {name for name, kind, _, _ in self.joints.values() if kind in MOVABLE}

    def chain_joints(self, tip: str) -> set[str]:
        """The path's movable joints and every movable joint whose line of mimic leaders ends
        where a path joint's does."""
        ends = {self.coupled(name)[0] for name, kind, _, _ in self.path(tip) if kind in MOVABLE}
        return {name for name, kind, _, _ in self.joints.values() if kind in MOVABLE and self.coupled(name)[0] in ends}

    def coupled(self, joint: str) -> tuple[str, float, float]:
        """(the joint at the end of its line of mimic leaders, multiplier, offset): its position
        is multiplier * that joint's + offset."""
        by_name = {name: mimic for name, _, _, mimic in self.joints.values()}
        m, c = 1.0, 0.0
        for _ in by_name:  # q = m q_joint + c, one leader further each step (a cycle ends too)
            if by_name.get(joint) is None:
                break
            joint, mk, ck = by_name[joint]
            m, c = m * mk, m * ck + c
        return joint, m, c


def structure(path: Path) -> Structure | None:
    """Links and joints as the XML has them (from <robot> on), None if expat cannot read it."""
    text = path.read_bytes()
    start = text.find(b"<robot")
    s, stack = Structure(), []
    joint: dict = {}

    def begin(tag, attrib):
        if stack == ["robot"] and tag == "link":
            s.links.append(attrib.get("name"))
        elif stack == ["robot"] and tag == "joint":
            joint.clear()
            joint.update(name=attrib.get("name"), type=attrib.get("type"), mimic=None)
        elif stack[1:] == ["joint"] and stack[0] == "robot" and tag in ("parent", "child"):
            joint[tag] = attrib.get("link")
        elif stack[1:] == ["joint"] and tag == "mimic":
            joint["mimic"] = (
                attrib.get("joint"),
                float(attrib.get("multiplier", "1")),
                float(attrib.get("offset", "0")),
            )
        stack.append(tag)

    def end(tag):
        stack.pop()
        if stack == ["robot"] and tag == "joint" and "child" in joint:
            s.joints[joint["child"]] = (joint["name"], joint["type"], joint.get("parent"), joint["mimic"])

    parser = xml.parsers.expat.ParserCreate()
    parser.StartElementHandler, parser.EndElementHandler = begin, end
    try:
        parser.Parse(text[max(start, 0) :], True)
    except xml.parsers.expat.ExpatError:
        return None
    return s if s.links else None


# --- what each reader makes of a file -----------------------------------------------------------


@dataclass
class Read:
    """One file: Pinocchio's reading (nv, or its error), robotgen's as a tree and as a chain
    (a system, or the refusal's 'LINE:COL: message')."""

    source: str
    name: str  # relative to the source directory
    path: Path
    structure: Structure | None
    pinocchio: int | str
    tree: object | str
    chain: object | str | None  # None: no link with a movable joint above it
    tip: str | None

    @property
    def builds(self) -> bool:
        return not isinstance(self.tree, str) and not isinstance(self.chain, str) and self.chain is not None


@contextlib.contextmanager
def quiet_stderr():
    """urdfdom writes its complaints to the C stderr: hidden while Pinocchio reads."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(devnull)
        os.close(saved)


def pinocchio_model(path: Path):
    import pinocchio as pin

    with quiet_stderr():
        return pin.buildModelFromUrdf(str(path))


def _refusal(error: UserError, path: Path) -> str:
    return f"{error.location.line}:{error.location.col}: {error.message}".replace(str(path), Path(path).name)


def read(source: str, path: Path) -> Read:
    try:
        pinocchio: int | str = pinocchio_model(path).nv
    except (RuntimeError, ValueError) as e:
        pinocchio = str(e).splitlines()[0].replace(f"The file {path} does", "the file does")
    s = structure(path)
    tip = s.deepest() if s is not None else None
    try:
        tree: object | str = load_urdf_tree_system(str(path), name="swept_tree")
    except UserError as e:
        tree = _refusal(e, path)
    chain: object | str | None = None
    if tip is not None:
        try:
            chain = load_urdf_system(str(path), tip, name="swept_chain")
        except UserError as e:
            chain = _refusal(e, path)
    elif isinstance(tree, str):
        chain = tree
    return Read(source, str(path.relative_to(sources()[source])), path, s, pinocchio, tree, chain, tip)


# --- against Pinocchio ---------------------------------------------------------------------------


def rel_err(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def compare(system, path: Path, expected: set[str], structure: Structure, seed: int = 0) -> dict[str, float]:
    """Worst relative error of M, g, inverse dynamics, C and J of ``system`` against
    Pinocchio's model of ``path`` at N_STATES random states, every joint outside ``expected``
    locked at 0 (a continuous joint at its neutral (1, 0)) with no velocity: the full model's
    rows and columns of the kept joints are then the locked model's. robotgen's joints must be
    exactly ``expected``; its friction is Pinocchio's damping as viscous and Pinocchio's
    friction as smoothed Coulomb friction (spec-format.md); gravity -9.81 along the base's z.
    A mimic joint (``structure.coupled``) is put at multiplier * q + offset of the joint its
    leaders end at, and Pinocchio's results are taken to those joints' coordinates:
    S^T M S, S^T tau, S^T C S, J S."""
    import pinocchio as pin

    from robotgen.symbolic import kernels_for

    leaf = system.nodes[system.root].leaf
    names = [j.name for j in leaf.joints]
    assert set(names) == expected, (sorted(names), sorted(expected))
    ends = [structure.coupled(name) for name in names]
    coordinates = [j.name for j in leaf.coordinate_joints]  # robotgen's order of them
    assert sorted(coordinates) == sorted({end for end, _, _ in ends}), (coordinates, ends)
    S = np.zeros((len(names), len(coordinates)))
    for i, (end, m, _) in enumerate(ends):
        S[i, coordinates.index(end)] = m
    offset = np.array([c for _, _, c in ends])
    model = pinocchio_model(path)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    R = data.oMf[model.getFrameId(leaf.base_link, pin.BODY)].rotation  # the base in Pinocchio's world
    model.gravity.linear = R @ np.array([0.0, 0.0, -9.81])
    tip = model.getFrameId(leaf.tip_link, pin.BODY)
    idx = np.array([model.joints[model.getJointId(n)].idx_v for n in names])
    assert all(model.joints[model.getJointId(n)].nv == 1 for n in names)
    damping, friction = model.damping[idx], model.friction[idx]
    f = {
        k.name: k.function
        for k in kernels_for(system)
        if k.name in ("mass", "gravity", "inverse_dynamics", "coriolis", "jacobian")
    }
    n = len(coordinates)
    rng = np.random.default_rng(seed)
    worst: dict[str, float] = {}
    for _ in range(N_STATES):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, n), rng.normal(size=n) * 2.0, rng.normal(size=n) * 5.0
        v, a, w = np.zeros(model.nv), np.zeros(model.nv), np.zeros(model.nv)
        v[idx], a[idx], w[idx] = S @ q + offset, S @ qd, S @ qdd
        qp = pin.integrate(model, pin.neutral(model), v)  # a continuous joint: (cos q, sin q)
        M = np.array(pin.crba(model, data, qp)).reshape(model.nv, model.nv)  # (6,) and (1, 1) when nv = 1
        M = np.triu(M) + np.triu(M, 1).T
        vj = S @ qd
        tau = pin.rnea(model, data, qp, a, w)[idx] + damping * vj + friction * np.tanh(vj / leaf.coulomb_smoothing)
        J = np.array(pin.computeFrameJacobian(model, data, qp, tip, pin.LOCAL_WORLD_ALIGNED)).reshape(6, -1)[:, idx]
        C = np.array(pin.computeCoriolisMatrix(model, data, qp, a)).reshape(model.nv, model.nv)[np.ix_(idx, idx)]
        errs = {
            "mass": rel_err(np.array(f["mass"](q)).reshape(n, n), S.T @ M[np.ix_(idx, idx)] @ S),
            "gravity": rel_err(
                np.array(f["gravity"](q)).ravel(), S.T @ pin.computeGeneralizedGravity(model, data, qp)[idx]
            ),
            "inverse_dynamics": rel_err(np.array(f["inverse_dynamics"](q, qd, qdd)).ravel(), S.T @ tau),
            "coriolis": rel_err(np.array(f["coriolis"](q, qd)).reshape(n, n), S.T @ C @ S),
            "jacobian": rel_err(np.array(f["jacobian"](q)).reshape(6, n), np.vstack([R.T @ J[:3], R.T @ J[3:]]) @ S),
        }
        for key, e in errs.items():
            worst[key] = max(worst.get(key, 0.0), e)
    return worst


# --- the tables of docs/robots.md ----------------------------------------------------------------


def _cell(text: str) -> str:
    """A refusal as code (its <tags> shown as written), a reader's verdict as text."""
    return text if text in ("builds", "the same", "no movable joint") else "`" + text.replace("|", "\\|") + "`"


def _folder(name: str) -> str:
    return name.split("/")[0] + "/" if "/" in name else name


def _listed(folder: str, names: list[str]) -> str:
    """A file by its name, several of one folder together."""
    return f"`{names[0]}`" if len(names) == 1 else f"`{folder}` ({len(names)} files)"


def _nothing(r: Read) -> bool:
    """No movable joint for any reader."""
    return (
        r.pinocchio == 0 and r.tip is None and isinstance(r.tree, str) and "no movable joint below base link" in r.tree
    )


def body(reads: list[Read]) -> list[str]:
    """One row per file robotgen refuses (as a tree or as a chain) with each reader's answer
    (the files of one folder refused alike in one row), then the files without a movable joint."""
    lines = [
        "| file | Pinocchio | robotgen, as a tree | robotgen, as a chain to its deepest link |",
        "| --- | --- | --- | --- |",
    ]
    rows: dict[tuple[str, str, str, str], list[str]] = {}
    for r in reads:
        if r.builds or _nothing(r):
            continue
        pin_text = f"reads it (nv = {r.pinocchio})" if isinstance(r.pinocchio, int) else r.pinocchio
        tree = "builds" if not isinstance(r.tree, str) else r.tree
        chain = (
            "builds"
            if not isinstance(r.chain, str) and r.chain is not None
            else "no movable joint"
            if r.chain is None
            else r.chain
            if r.chain != r.tree
            else "the same"
        )
        rows.setdefault((_folder(r.name), pin_text, tree, chain), []).append(r.name)
    for (folder, pin_text, *cells), names in rows.items():
        pin_cell = pin_text if pin_text.startswith("reads it") else f"refuses it: {_cell(pin_text)}"
        lines.append(f"| {_listed(folder, names)} | {pin_cell} | " + " | ".join(_cell(c) for c in cells) + " |")
    groups: dict[str, list[str]] = {}
    for r in reads:
        if _nothing(r):
            groups.setdefault(_folder(r.name), []).append(r.name)
    if groups:
        listed = ", ".join(_listed(folder, names) for folder, names in groups.items())
        lines += ["", f'No movable joint (Pinocchio: nv = 0; robotgen: "no movable joint below base link"): {listed}.']
    return lines


def table(source: str, reads: list[Read]) -> str:
    """The generated section of one collection: counts, then ``body``."""
    builds = [r for r in reads if r.builds]
    nothing = [r for r in reads if _nothing(r)]
    refused = [r for r in reads if not r.builds and not _nothing(r)]
    pin_reads = [r for r in refused if isinstance(r.pinocchio, int)]
    return "\n".join(
        [
            f"<!-- {source}: generated by `python tests/urdf_sweep.py --write`; tests/dynamics/test_urdf_sweep.py checks "
            "it -->",
            f"{len(reads)} files: {len(builds)} build unmodified, as a tree and as a chain, and agree with Pinocchio; "
            f"{len(refused)} are refused ({len(pin_reads)} of them read by Pinocchio); {len(nothing)} have no movable "
            "joint.",
            "",
            *body(reads),
        ]
    )


def documented_files(source: str) -> list[Path]:
    """The files that the section of ``source`` names (a folder: every file in it)."""
    section = current_section(source)
    names = re.findall(r"^\| `([^`]+)`", section, re.MULTILINE)  # each row's first cell
    nothing = section.partition("No movable joint")[2].partition("):")[2]
    names += re.findall(r"`([^`]+)`", nothing)
    root = sources()[source]
    out: list[Path] = []
    for name in names:
        out += sorted((root / name).rglob("*.urdf")) if name.endswith("/") else [root / name]
    return sorted(set(out))


def section_bounds(text: str, source: str) -> tuple[int, int]:
    """Where the generated section of ``source`` starts and ends in docs/robots.md."""
    start = text.index(f"<!-- {source}: generated")
    end = text.find("\n\n## ", start)
    return start, len(text.rstrip("\n")) if end < 0 else end


def current_section(source: str) -> str:
    text = DOCS.read_text()
    start, end = section_bounds(text, source)
    return text[start:end]


def write(sections: dict[str, str]) -> None:
    text = DOCS.read_text()
    for source, section in sections.items():
        start, end = section_bounds(text, source)
        text = text[:start] + section + text[end:]
    DOCS.write_text(text if text.endswith("\n") else text + "\n")


def read_all(source: str) -> list[Read]:
    return [read(source, p) for p in files(source)]


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the tables of docs/robots.md")
    args = parser.parse_args()
    made = {source: table(source, read_all(source)) for source in sources()}
    if args.write:
        write(made)
    else:
        print("\n\n".join(made.values()))
    missing = [s for s in ("pybullet_data",) if s not in made]
    if missing:
        print(f"not swept (not installed): {', '.join(missing)}", file=sys.stderr)
