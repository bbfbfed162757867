"""Scaling benchmark: build seconds and ns per call against degrees of freedom.

    python bench/scaling.py [--quick] [--sizes 2 4 ...] [--no-humanoid]
                            [--json bench/scaling.json] [--png bench/scaling.png]

Models: synthetic serial chains of n = 2, 4, 6, 8, 12, 16, 20, 25, 30 revolute links (one
fixed seed; chain n is the first n links of chain 30: joint frames turned by exact 90-degree
rotations or none, so consecutive axes alternate between perpendicular and parallel; link
offsets ~0.1 m, masses ~1 kg, box inertias turned by a random rotation) and a humanoid tree,
iCub's 32 revolute joints below its root link (example-robot-data's icub.urdf read with
robotgen.frontend.urdf.read_urdf_tree; fk/jacobian at the right hand). --quick: chains n = 2, 6 only.

For each model, what `robotgen build` does (robotgen.emit.pipeline.build), timed in three parts:
  graph    robotgen.symbolic.kernels_for(system) (the CasADi SX graphs, CSE included);
  emit     the rest of the build minus its compile step: the C text, header, wrapper and
           manifest;
  compile  the compile step inside it (robotgen.emit.compile.compile_extension, timed by
           wrapping it; it compiles in one compiler process, so one core is used).
build = graph + emit + compile, against a budget of 60 s; builds run one after another with
nothing else of the bench running. Each module is imported and its timed functions checked
once against CasADi's evaluation of the same graphs (1e-9 relative). Then bench/harness.c is
compiled against each model's kernel sources with bench/run.py's command (cc -O2; these
compiles, untimed, run os.cpu_count() at a time) and run one model at a time through
bench/run.py's run_c: ns per call, min over 7 repeats of >= 50 ms each.

Prints a table, writes bench/scaling.json and bench/scaling.png (ns per call vs dof, log y;
build seconds vs dof). A model over the budget is reported (which, by how much), never skipped.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

import run as bench_run  # noqa: E402  (bench/run.py: the C harness driver)

SIZES = [2, 4, 6, 8, 12, 16, 20, 25, 30]
QUICK_SIZES = [2, 6]
FUNCTIONS = ["mass", "inverse_dynamics", "gravity", "jacobian", "coriolis", "forward_dynamics"]
BUDGET_S = 60.0
SEED = 2024
HUMANOID = ("icub", "icub_description/robots/icub.urdf")
HUMANOID_TIP = "r_hand"  # fk/jacobian at the right hand: 10 joints deep (torso 3, arm 7)
CHECK_TOL = 1e-9


# --- models -------------------------------------------------------------------------------


def _rot(axis: str, quarter_turns: int) -> np.ndarray:
    """Exact rotation by quarter_turns * 90 degrees about x or y (integer entries)."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][quarter_turns % 4]
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], float)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], float)


def _random_rotation(rng) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q if np.linalg.det(Q) > 0 else -Q


def synthetic_chain(n: int, seed: int = SEED):
    """A serial chain of n revolute joints about their z axes (see the module docstring)."""
    from robotgen.model.chain import REVOLUTE, Body, Joint, KinematicTree, Limits

    rng = np.random.default_rng(seed)
    joints = []
    for i in range(n):
        T = np.eye(4)
        if i > 0:  # the base joint stands upright
            turn = rng.integers(5)  # 0..3: a quarter turn about +-x or +-y; 4: none (parallel axes)
            if turn < 4:
                T[:3, :3] = _rot("xy"[turn // 2], 1 if turn % 2 == 0 else 3)
            T[:3, 3] = [
                round(rng.uniform(0.0, 0.1), 3) if rng.random() < 0.5 else 0.0,
                0.0,
                round(rng.uniform(0.05, 0.15), 3),
            ]
        mass = round(rng.uniform(0.6, 1.4), 3)
        a, b, c = rng.uniform(0.04, 0.12, 3)  # a solid box: valid principal moments
        principal = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        R = _random_rotation(rng)
        body = Body(
            mass,
            np.round(np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(0.02, 0.06)]), 3),
            R @ np.diag(principal) @ R.T,
        )
        joints.append(
            Joint(
                f"j{i + 1}",
                REVOLUTE,
                i - 1,
                T,
                np.array([0.0, 0.0, 1.0]),
                body,
                limits=Limits(-np.pi, np.pi, 2.0, 50.0),
            )
        )
    tool = np.eye(4)
    tool[2, 3] = 0.1
    return KinematicTree(
        f"chain{n}", tuple(joints), n - 1, tool, np.array([0.0, 0.0, -9.81]), base_link="base", tip_link="tip"
    )


def humanoid():
    from robotgen.frontend.urdf import read_urdf_tree

    name, rel = HUMANOID
    path = bench_run.robots_dir() / rel
    return read_urdf_tree(str(path), tip=HUMANOID_TIP, name=name).tree, path


def single_leaf_system(tree, source: str = "", sha: str = ""):
    """Without the derivative functions, so that every size builds the same kernels (the
    derivatives are timed by bench/run.py against Pinocchio's)."""
    from robotgen.model.derivatives import DerivativeSettings
    from robotgen.model.system import DefineNode, RobotSystem

    return RobotSystem(
        tree.name,
        source,
        sha,
        {tree.name: DefineNode(tree.name, tree)},
        tree.name,
        derivatives=DerivativeSettings(include=False),
    )


# --- one model ----------------------------------------------------------------------------


def timed_build(system, out: Path) -> dict:
    """robotgen.emit.pipeline.build (compile included), with the graphs and the compile step timed apart."""
    from robotgen.emit import compile as compiler
    from robotgen.emit.pipeline import build

    compile_s = []
    original = compiler.compile_extension

    def timed_compile(*args, **kwargs):
        t = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            compile_s.append(time.perf_counter() - t)

    compiler.compile_extension = timed_compile
    try:
        t0 = time.perf_counter()
        built = build(system, out)
        t_build = time.perf_counter() - t0
    finally:
        compiler.compile_extension = original
    t_compile = sum(compile_s)
    return {
        "kernels": built.kernels,
        "graph_s": built.graph_seconds,
        "emit_s": t_build - built.graph_seconds - t_compile,
        "compile_s": t_compile,
        "compile_timed_apart": bool(compile_s),
        "build_s": t_build,
    }


def load_module(out: Path, name: str):
    from robotgen.emit.compile import extension_suffix

    spec = importlib.util.spec_from_file_location(name, out / f"{name}{extension_suffix()}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def check_module(module, kernels: dict, nq: int) -> float:
    """The compiled module runs and agrees with CasADi's evaluation of the same graphs."""
    rng = np.random.default_rng(7)
    args = [rng.uniform(-np.pi, np.pi, nq), rng.uniform(-2, 2, nq), rng.uniform(-2, 2, nq)]
    worst = 0.0
    for fn in FUNCTIONS:
        k = bench_run.ARITY[fn]
        got = np.asarray(getattr(module, fn)(*args[:k]), float).ravel()
        want = np.asarray(kernels[fn].function(*args[:k]), float).ravel()
        if got.shape != want.shape or not np.all(np.isfinite(got)):
            sys.exit(f"bench: {module.__name__}.{fn}: shape {got.shape} or non-finite output")
        worst = max(worst, bench_run.rel_err(got, want))
    if worst > CHECK_TOL:
        sys.exit(
            f"bench: {module.__name__}: the compiled module and CasADi disagree ({worst:.1e}); not timing wrong code"
        )
    return worst


def build_model(tree, kind: str, tmp: Path, source: Path | None = None) -> dict:
    """Timed build, then import the module and check it (nothing else of ours runs meanwhile)."""
    import hashlib

    sha = hashlib.sha256(source.read_bytes()).hexdigest() if source else ""
    system = single_leaf_system(tree, str(source or ""), sha)
    out = tmp / f"build-{tree.name}"
    print(f"bench: {tree.name} (dof {tree.nq}): building ...", end="", flush=True)
    b = timed_build(system, out)
    kernels = {k.name: k for k in b.pop("kernels")}
    print(
        f" {b['build_s']:.1f} s (graph {b['graph_s']:.1f}, emit {b['emit_s']:.1f}, compile {b['compile_s']:.1f})",
        flush=True,
    )
    worst = check_module(load_module(out, tree.name), kernels, tree.nq)
    ops = bench_run.op_counts(out)
    over = b["build_s"] - BUDGET_S
    return {
        "model": tree.name,
        "kind": kind,
        "dof": tree.nq,
        "tip_link": tree.tip_link,
        "depth": max(len(tree.support(i)) for i in range(tree.nq)),
        **b,
        "over_budget_s": over if over > 0 else 0.0,
        "check_vs_casadi": worst,
        "arithmetic_ops": {fn: ops.get(fn, {}).get("arithmetic_ops") for fn in FUNCTIONS},
        "_out": out,
    }


def compile_harnesses(rows: list[dict], tmp: Path) -> None:
    """Compiles every model's C harness, os.cpu_count() at a time: after all builds are timed
    and before any harness runs, so neither timing shares the machine with these compiles.
    run_c then finds the executable in place and only runs it."""
    from concurrent.futures import ThreadPoolExecutor

    def one(r):
        work = tmp / f"c-{r['model']}"
        work.mkdir(parents=True, exist_ok=True)
        res = subprocess.run(
            bench_run.harness_command(r["_out"], r["model"], r["dof"], work / "harness"),
            capture_output=True,
            text=True,
        )
        if res.returncode != 0:
            raise RuntimeError(f"compiling the C harness for {r['model']} failed:\n{res.stderr[-2000:]}")

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        list(pool.map(one, sorted(rows, key=lambda r: -r["compile_s"])))  # longest first
    print(
        f"bench: compiled {len(rows)} C harnesses in {time.perf_counter() - t0:.0f} s ({os.cpu_count()} at a time)",
        flush=True,
    )


def time_model(r: dict, tmp: Path) -> None:
    c = bench_run.run_c(r["_out"], r["model"], r["dof"], FUNCTIONS, tmp / f"c-{r['model']}")
    r["ns"] = {fn: c["results"][fn]["ns_min"] for fn in FUNCTIONS}
    r["ns_median"] = {fn: c["results"][fn]["ns_median"] for fn in FUNCTIONS}
    r["c_command"], r["c_compiler"] = c["command"], c["compiler"]
    print(f"bench: timed {r['model']}", flush=True)


# --- report -------------------------------------------------------------------------------

SHORT = {
    "mass": "mass",
    "inverse_dynamics": "inv_dyn",
    "gravity": "gravity",
    "jacobian": "jacobian",
    "coriolis": "coriolis",
    "forward_dynamics": "fwd_dyn",
}


def table(rows: list[dict]) -> str:
    head = ["model", "dof", "graph s", "emit s", "compile s", "build s"] + [f"{SHORT[f]} ns" for f in FUNCTIONS]
    lines = [head]
    for r in rows:
        lines.append(
            [
                r["model"],
                str(r["dof"]),
                f"{r['graph_s']:.1f}",
                f"{r['emit_s']:.1f}",
                f"{r['compile_s']:.1f}",
                f"{r['build_s']:.1f}" + (" !" if r["over_budget_s"] else ""),
            ]
            + [f"{r['ns'][f]:.0f}" for f in FUNCTIONS]
        )
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    fmt = lambda row: "  ".join(s.rjust(w) if i else s.ljust(w) for i, (s, w) in enumerate(zip(row, widths)))  # noqa: E731
    return "\n".join([fmt(lines[0]), fmt(["-" * w for w in widths])] + [fmt(r) for r in lines[1:]])


def plot(rows: list[dict], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chains = [r for r in rows if r["kind"] == "chain"]
    trees = [r for r in rows if r["kind"] != "chain"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    for k, fn in enumerate(FUNCTIONS):
        color = f"C{k}"
        ax1.plot([r["dof"] for r in chains], [r["ns"][fn] for r in chains], "o-", color=color, label=fn)
        for r in trees:
            ax1.plot(r["dof"], r["ns"][fn], "*", color=color, markersize=12)
    ax1.set_yscale("log")
    ax1.set_xlabel("degrees of freedom")
    ax1.set_ylabel("ns per call (generated C, cc -O2)")
    ax1.set_title(
        "Generated C: ns per call" + (f" (stars: {', '.join(r['model'] for r in trees)} tree)" if trees else "")
    )
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=8)
    x = [r["dof"] for r in chains]
    for key, style, label in (
        ("build_s", "o-", "build (total)"),
        ("graph_s", "s--", "CasADi graphs"),
        ("emit_s", "^--", "C emit"),
        ("compile_s", "v--", "compile"),
    ):
        (line,) = ax2.plot(x, [r[key] for r in chains], style, label=label)
        for r in trees:
            ax2.plot(r["dof"], r[key], "*", color=line.get_color(), markersize=12)
    ax2.axhline(BUDGET_S, color="red", linestyle=":", label=f"budget {BUDGET_S:.0f} s")
    ax2.set_xlabel("degrees of freedom")
    ax2.set_ylabel("seconds")
    ax2.set_title("Build time (codegen + compile)")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help=f"smoke subset: chains n = {QUICK_SIZES} only")
    ap.add_argument("--sizes", nargs="*", type=int, help=f"chain sizes (default {SIZES})")
    ap.add_argument("--no-humanoid", action="store_true", help="skip the humanoid tree")
    ap.add_argument("--json", default=str(HERE / "scaling.json"))
    ap.add_argument("--png", default=str(HERE / "scaling.png"))
    args = ap.parse_args(argv)

    sizes = args.sizes if args.sizes is not None else (QUICK_SIZES if args.quick else SIZES)
    with_humanoid = not (args.quick or args.no_humanoid)
    tmp = Path(tempfile.mkdtemp(prefix="robotgen-scaling-"))
    t_start = time.perf_counter()
    try:
        rows = [build_model(synthetic_chain(n), "chain", tmp) for n in sizes]
        if with_humanoid:
            tree, path = humanoid()
            rows.append(build_model(tree, f"tree ({HUMANOID[1]}, tip {tree.tip_link})", tmp, path))
        compile_harnesses(rows, tmp)
        for r in rows:
            time_model(r, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for r in rows:
        del r["_out"]
    total = time.perf_counter() - t_start

    print(
        f"\nbench: build seconds and ns per call (generated C, {' '.join(bench_run.CFLAGS)}; "
        f"min over repeats) against dof; budget {BUDGET_S:.0f} s per build"
    )
    print(table(rows))
    over = [r for r in rows if r["over_budget_s"] > 0]
    for r in over:
        slowest = max(("graph_s", "emit_s", "compile_s"), key=lambda k: r[k])
        print(
            f"bench: OVER BUDGET: {r['model']} (dof {r['dof']}) builds in {r['build_s']:.1f} s, "
            f"{r['over_budget_s']:.1f} s over {BUDGET_S:.0f} s (largest part: {slowest[:-2]} "
            f"{r[slowest]:.1f} s)"
        )
    if not over:
        print(f"bench: every build within {BUDGET_S:.0f} s")
    print(f"bench: scaling run took {total:.0f} s")

    result = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "casadi": __import__("casadi").__version__,
        "quick": args.quick,
        "seed": SEED,
        "budget_s": BUDGET_S,
        "total_s": total,
        "units": "seconds; ns per call of the generated C (min over 7 repeats), ns_median the median",
        "notes": [
            "build_s = graph_s + emit_s + compile_s: robotgen.emit.pipeline.build, its kernels_for(system) "
            "and its compile step (one compiler process) timed apart",
            "chains: synthetic revolute chains, fixed seed, chain n = first n links of the longest",
            f"humanoid: {HUMANOID[1]} read with robotgen.frontend.urdf.read_urdf_tree (fixed base)",
        ],
        "over_budget": [
            {"model": r["model"], "dof": r["dof"], "build_s": r["build_s"], "over_s": r["over_budget_s"]} for r in over
        ],
        "models": rows,
    }
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    plot(rows, Path(args.png))
    print(f"bench: wrote {args.json} and {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
