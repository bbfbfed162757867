"""C. S. G. Lee and B. H. Lee, "Resolved Motion Adaptive Control for Mechanical Manipulators"
(1983), reproduced with robotgen on the PUMA 560 of specs/puma560_rmac.yaml: Table 1 (the
operations of one sampling period, stage by stage) beside robotgen's counts, the one-step
control's closed loop, a long run with payload steps against the same controller with its
identification frozen and against resolved acceleration control, and the choices robotgen
made where the paper's controller does not hold (each run once with the paper's choice).

    python examples/papers/lee_lee_1983.py [--quick] [-o DIR]

The paper reports Table 1 and no simulation. Its controller as printed (eq 37's exponential
forgetting, no constant term in eq 29, weights of the authors' choosing) is run here as the
"first defaults" variant: robotgen's first version of this law, whose hand walked away over
10 s. Modules are built from copies of specs/puma560_rmac.yaml in a temporary directory.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import itertools
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from ruamel.yaml import YAML  # noqa: E402

from robotgen.cli import main as robotgen  # noqa: E402
from robotgen.emit.pipeline import BuildOptions, build  # noqa: E402
from robotgen.frontend import load_system  # noqa: E402
from robotgen.model.simulation import PayloadChange  # noqa: E402
from robotgen.simulation import hand as hand_simulation  # noqa: E402
from robotgen.simulation import tree as simulate  # noqa: E402
from robotgen.symbolic import module_extras  # noqa: E402
from robotgen.symbolic.root_laws.resolved_adaptive import closed_loop  # noqa: E402

SPEC = ROOT / "specs" / "puma560_rmac.yaml"
DEFAULT_OUTPUT = Path("generated/papers/lee_lee_1983")
# the long run: payloads picked up, changed (off the wrist axis) and dropped
LONG_RUN = {
    False: (20.0, (PayloadChange(1.0, 2.0), PayloadChange(7.0, 5.0, (0.05, 0.05, 0.03)), PayloadChange(14.0, 0.0))),
    True: (4.0, (PayloadChange(1.0, 2.0),)),
}
# one change for the variants: 5 kg off the wrist axis at 1 s, 10 s (quick: the first two, 3 s)
VARIANT_CHANGE = PayloadChange(1.0, 5.0, (0.05, 0.05, 0.03))
VARIANT_DURATION = {False: 10.0, True: 3.0}
# robotgen's choices, each undone once (settings of resolved_adaptive)
VARIANTS = {
    "robotgen's defaults": {},
    "first defaults (eq 37 as printed, no c, hand-set Q, R)": {
        "q": [1e6, 1e6, 1e4, 1e4],
        "r": 1e-5,
        "forgetting": 0.97,
        "initial_covariance": 100,
        "affine": False,
        "directional": False,
    },
    "no affine term c": {"affine": False},
    "eq 37's forgetting of all of P": {"directional": False},
    "B not trusted (P_0 on B's block 1e-5)": {"initial_covariance": {"B": 1e-5}},
}
_SERIAL = itertools.count()  # one extension module per name in a process


class Builds:
    """Copies of the spec with changed settings, each built into ``root`` under a name of
    its own, and the resolved acceleration controller robotgen simulate compares with."""

    def __init__(self, root: Path):
        self.root = root
        self.yaml = YAML(typ="safe")
        self.yaml.default_flow_style = None

    def variant(self, settings: dict):
        """(module, system) of the spec with ``settings`` merged into resolved_adaptive's."""
        data = self.yaml.load(SPEC)
        name = data["name"] = f"lee_lee_{next(_SERIAL)}"
        data["nodes"]["rmac"]["control"]["resolved_adaptive"].update(settings)
        path = self.root / f"{name}.yaml"
        with open(path, "w") as f:
            self.yaml.dump(data, f)
        with contextlib.redirect_stdout(io.StringIO()):
            status = robotgen(["build", str(path), "-o", str(self.root / name), "-q"])
        if status != 0:
            raise RuntimeError(f"robotgen build {path} exited with status {status}")
        return simulate.load_module(self.root / name, name), load_system(str(path))

    def comparison(self, system):
        twin = hand_simulation.comparison_system(system)
        twin = dataclasses.replace(twin, name=f"lee_lee_rac_{next(_SERIAL)}")
        build(twin, self.root / twin.name, BuildOptions(reports=False))  # as robotgen simulate builds it
        return simulate.load_module(self.root / twin.name, twin.name)


# ---- Table 1 ---------------------------------------------------------------------------------


def table_1(system) -> tuple[dict, dict[str, float]]:
    counts = module_extras(system)[0]["hand_control"]["operation_counts"]
    numbers = {}
    for row in counts["rows"]:
        key = f"table1 {row['part']} {row['stage']}"
        for who in ("paper", "robotgen"):
            for kind in ("mul", "add"):
                numbers[f"{key} {who} {kind}"] = float(row[who][kind])
    for total in ("feedforward", "feedback", "period", "sequential"):
        for who in ("paper", "robotgen"):
            for kind in ("mul", "add"):
                numbers[f"table1 {total} {who} {kind}"] = float(counts[who][total][kind])
    numbers["table1 emitted step mul"] = float(counts["step"]["mul"])
    numbers["table1 emitted step add"] = float(counts["step"]["add"])
    return counts, numbers


def plot_table_1(counts: dict, path: Path) -> None:
    plt = _pyplot()
    rows = counts["rows"]
    labels = [f"{r['part']} {r['stage']}: {r['name']}" for r in rows]
    labels.append("period (feedforward and feedback in parallel)")
    paper = [r["paper"]["mul"] + r["paper"]["add"] for r in rows] + [sum(counts["paper"]["period"].values())]
    ours = [r["robotgen"]["mul"] + r["robotgen"]["add"] for r in rows]
    ours.append(counts["robotgen"]["period"]["mul"] + counts["robotgen"]["period"]["add"])
    y = np.arange(len(labels))[::-1]
    fig, ax = plt.subplots(figsize=(10, 5.5))
    ax.barh(y + 0.2, paper, 0.4, label="Lee and Lee 1983, Table 1")
    ax.barh(y - 0.2, ours, 0.4, label="robotgen (PUMA 560, puma560_rmac.yaml)")
    for yy, value in zip(y, ours):
        ax.annotate(f" {value}", (value, yy - 0.2), va="center", fontsize=7)
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_xlabel("multiplications + additions per sampling period")
    ax.legend(loc="upper right")
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title("Table 1: one period of resolved motion adaptive control")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ---- runs ------------------------------------------------------------------------------------


def long_run(builds: Builds, quick: bool, out: Path) -> dict[str, float]:
    module, system = builds.variant({})
    duration, changes = LONG_RUN[quick]
    settings = dataclasses.replace(system.simulation, duration=duration, payload_changes=changes)
    result = hand_simulation.run(module, system, settings, builds.comparison(system))
    hand_simulation.plot(
        result, out / "long_run.png", f"PUMA 560 under resolved motion adaptive control, {duration:g} s, payload steps"
    )
    numbers = {}
    for r in result.runs:
        numbers[f"long {r.key} before"] = 1e3 * r.rms(result.before)
        for k, change in enumerate(changes):
            numbers[f"long {r.key} change {k + 1} first second"] = 1e3 * r.rms(result.window(change.at))
            end = changes[k + 1].at if k + 1 < len(changes) else result.t[-1] + 1
            numbers[f"long {r.key} change {k + 1} last second"] = 1e3 * r.rms(
                (result.t > end - 1 - 1e-9) & (result.t < end - 1e-9)
            )
        numbers[f"long {r.key} max torque step"] = r.largest_torque_step()
    return numbers


def variants(builds: Builds, quick: bool) -> tuple[dict[str, float], list[tuple]]:
    """Each variant under the same 5 kg step: RMS hand error over the first second after it and
    over the last second [mm], the largest torque step [N m], or the time it diverged."""
    numbers, rows = {}, []
    chosen = list(VARIANTS.items())[:2] if quick else list(VARIANTS.items())
    for k, (label, settings) in enumerate(chosen):
        module, system = builds.variant(settings)
        s = dataclasses.replace(system.simulation, duration=VARIANT_DURATION[quick], payload_changes=(VARIANT_CHANGE,))
        loop = closed_loop(system)
        try:
            result = hand_simulation.run(module, system, s, keys=("adaptive",))
        except simulate.SimulationError as e:
            rows.append((label, loop["spectral_radius"], None, None, None, str(e).split(" (q = ")[0]))
            numbers[f"variant {k} diverged"] = 1.0
            continue
        adaptive = result.runs[0]
        first, last = 1e3 * adaptive.rms(result.window(VARIANT_CHANGE.at)), 1e3 * adaptive.rms(result.last_window)
        step = adaptive.largest_torque_step()
        numbers.update(
            {
                f"variant {k} radius": loop["spectral_radius"],
                f"variant {k} first second": first,
                f"variant {k} last second": last,
                f"variant {k} max torque step": step,
            }
        )
        rows.append((label, loop["spectral_radius"], first, last, step, ""))
    return numbers, rows


# ---- the report ------------------------------------------------------------------------------


def write_report(path: Path, counts: dict, numbers: dict, variant_rows: list, quick: bool) -> None:
    duration, changes = LONG_RUN[quick]
    lines = [
        "# Lee and Lee 1983, resolved motion adaptive control, reproduced",
        "",
        "PUMA 560 of `specs/puma560_rmac.yaml`" + (" (quick mode: short runs)." if quick else "."),
        "",
        "## Table 1: operations of one sampling period",
        "",
        "The paper computes the feedforward and the feedback in parallel, and the two parts of "
        "feedback stage 1 in parallel; a period costs the larger part. robotgen's counts are of the "
        "graphs it emits (CasADi's instructions after common subexpressions; divisions, square roots "
        "and selections are counted apart, as `other`).",
        "",
        "| stage | paper mul | paper add | robotgen mul | robotgen add | trig | other | robotgen computes more |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in counts["rows"]:
        p, g = r["paper"], r["robotgen"]
        more = r["note"]
        lines.append(
            f"| {r['part']} {r['stage']}: {r['name']} | {p['mul']} | {p['add']} | {g['mul']} | {g['add']} | "
            f"{g['trig']} | {g['other']} | {more} |"
        )
    for total, label in (
        ("feedforward", "total feedforward"),
        ("feedback", "total feedback"),
        ("period", "**period** (in parallel)"),
        ("sequential", "every stage on one processor"),
    ):
        p, g = counts["paper"][total], counts["robotgen"][total]
        lines.append(f"| {label} | {p['mul']} | {p['add']} | {g['mul']} | {g['add']} | {g['trig']} | {g['other']} | |")
    step = counts["step"]
    lines += [
        f"| emitted step (its prologue and loops) | | | {step['mul']} | {step['add']} | {step['trig']} "
        f"| {step['other']} | |",
        "",
        "![Table 1](table1.png)",
        "",
        f"## A long run: {duration:g} s, payload steps",
        "",
        "The hand follows a 10 cm diagonal in the x-z plane at 0.5 Hz; the plant's hand picks up and "
        "drops payloads the controller is not told about. RMS hand position error [mm]:",
        "",
        "| run | before | "
        + " | ".join(f"{c.mass:g} kg at {c.at:g} s: first second | last second" for c in changes)
        + " | max torque step [N m] |",
        "| --- | ---: | " + " | ".join("---: | ---:" for _ in changes) + " | ---: |",
    ]
    for key, label in (
        ("adaptive", "adaptive"),
        ("frozen", "identification frozen"),
        ("rac", "resolved acceleration (Kp = 400, Kv = 40)"),
    ):
        cells = [f"{numbers[f'long {key} before']:.4f}"]
        for k in range(len(changes)):
            cells += [
                f"{numbers[f'long {key} change {k + 1} first second']:.4f}",
                f"{numbers[f'long {key} change {k + 1} last second']:.4f}",
            ]
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {numbers[f'long {key} max torque step']:.2f} |")
    lines += [
        "",
        "![long run](long_run.png)",
        "",
        f"## robotgen's choices, each undone ({VARIANT_CHANGE.mass:g} kg off the wrist axis at "
        f"{VARIANT_CHANGE.at:g} s, {VARIANT_DURATION[quick]:g} s)",
        "",
        "| variant | closed-loop radius at theta0 | RMS first second [mm] | RMS last second [mm] | "
        "max torque step [N m] |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for label, radius, first, last, step, failed in variant_rows:
        if failed:
            lines.append(f"| {label} | {radius:.6g} | {failed} | | |")
        else:
            lines.append(f"| {label} | {radius:.6g} | {first:.4f} | {last:.4f} | {step:.2f} |")
    path.write_text("\n".join(lines) + "\n")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def reproduce(out: Path, quick: bool = False) -> dict[str, float]:
    """Table 1, the closed loop, the long run and the variants: PNGs and report.md into
    ``out``; returns the numbers."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    system = load_system(str(SPEC))
    counts, numbers = table_1(system)
    plot_table_1(counts, out / "table1.png")
    with tempfile.TemporaryDirectory(prefix="lee-lee-") as tmp:
        builds = Builds(Path(tmp))
        numbers.update(long_run(builds, quick, out))
        variant_numbers, rows = variants(builds, quick)
        numbers.update(variant_numbers)
    write_report(out / "report.md", counts, numbers, rows, quick)
    return numbers


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="short runs, two variants")
    p.add_argument("-o", "--output", type=Path, default=DEFAULT_OUTPUT, help=f"default {DEFAULT_OUTPUT}")
    args = p.parse_args()
    if args.output.exists() and not args.output.is_dir():
        p.error(f"-o {args.output}: not a directory")
    numbers = reproduce(args.output, quick=args.quick)
    width = max(map(len, numbers))
    for k, v in numbers.items():
        print(f"{k:<{width}}  {v:.6g}")
    for f in sorted(args.output.iterdir()):
        print(f"wrote {f}")


if __name__ == "__main__":
    main()
