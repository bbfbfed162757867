"""robotgen's kernels against the code-generating peers: Pinocchio's code generation
(CppADCodeGen) and casadi_kin_dyn (Pinocchio traced into CasADi, then CasADi's C).

    python bench/code_generators.py [--arms ur5 panda iiwa] [--rounds N] [--quick] [--json bench/results.json]

For each arm (bench/peers/arms.py: the UR5 and the Panda as bench/run.py builds them, the KUKA
iiwa): robotgen builds it; each peer generates C for the same model (every variant of a
kernel: bench/peers/pinocchio_cg.py, bench/peers/casadi_kin_dyn_codegen.py); everything is
compiled with robotgen's kernels' flags (cc -std=c99 -O2 -ffp-contract=off) into one harness
(bench/peers/peer_harness.c) that checks, on its 256 random states, that every function agrees
with robotgen's module (relative difference <= 1e-9; what disagrees is not timed), then times
each kernel's functions in interleaved rounds. The ratio is peer ns / robotgen ns (> 1: robotgen
is faster), against the best variant of each peer. A peer that cannot be built here is
reported with the reason, and the rest goes on. The results go to the JSON file under
"code_generators", its other keys kept (bench/run.py, which writes bench/results.json, keeps this one).
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import run  # noqa: E402
from peers import arms, harness, pinocchio_cg  # noqa: E402
from peers import casadi_kin_dyn_peer as casadi_kin_dyn  # noqa: E402

CFLAGS, CHECK_TOL, KERNELS, NSETS = harness.CFLAGS, harness.CHECK_TOL, harness.KERNELS, harness.NSETS
HarnessError, PeerUnavailable = harness.HarnessError, pinocchio_cg.PeerUnavailable

PEERS = {"pinocchio_cg": "Pinocchio-cg", "casadi_kin_dyn": "casadi_kin_dyn"}
KERNEL_NAMES = {
    "mass": "mass matrix",
    "inverse_dynamics": "RNEA",
    "forward_dynamics": "forward dynamics (ABA, or CRBA + Cholesky traced)",
    "mass_inverse": "M⁻¹",
    "inverse_dynamics_derivatives": "∂RNEA",
    "forward_dynamics_derivatives": "∂FD",
}
GOALS = {k: 3.0 if k.endswith("derivatives") else 2.0 for k in KERNELS}  # issue 35's floors


def say(text: str) -> None:
    print(f"bench: {text}", flush=True)


def start_pinocchio_cg() -> tuple[pinocchio_cg.Generator | None, dict]:
    """The generator's compile, started in the background (minutes, once: cached)."""
    try:
        gen = pinocchio_cg.Generator(run.pinocchio_toolchain(run.cmeel_prefix()))
    except (PeerUnavailable, run.ToolchainError) as e:
        return None, {"error": str(e)}
    if not gen.cached:
        say("compiling Pinocchio's code generator (pinocchio_codegen.cpp, ~5 min; cached in bench/out/peers/)")
    return gen, gen.describe()


def peer_functions(arm, gen, status: dict) -> list:
    """Every peer function for ARM that compiles; a peer that cannot be built is recorded in
    STATUS with the reason."""
    found = []
    makers = {
        "casadi_kin_dyn": lambda: casadi_kin_dyn.functions(arm.name, arm.model_urdf),
        "pinocchio_cg": lambda: (gen.functions(arm.name, arm.model_urdf, arm.nq), {}),
    }
    for who, make in makers.items():
        if "error" in status[who]:
            continue
        try:
            functions, info = make()
            for source in sorted({f.source for f in functions}):
                harness.compile_object(source, CFLAGS, [])
        except (PeerUnavailable, HarnessError) as e:
            status[who] = {**status[who], "error": f"{arm.name}: {e}"}
            say(f"{PEERS[who]} not measured: {e}")
            continue
        status[who].update(info)
        found += functions
    return found


def measure(arm, peers: list, work: Path, rounds: int) -> dict:
    """ARM's harness: the check, then the timing of what agrees."""
    exe, rows = harness.build(arm, peers, work / "harness")
    differences = harness.check(arm, exe, rows)
    for row, diff in zip(rows, differences):
        row["max_difference"] = diff
    wrong = [r for r in rows if not r["max_difference"] <= CHECK_TOL]
    if any(r["who"] == "robotgen" for r in wrong):
        raise HarnessError(f"{arm.name}: robotgen's C and its module disagree: {wrong}")
    for r in wrong:
        say(
            f"{arm.name}: {r['who']} {r['variant']} ({r['kernel']}) disagrees with robotgen (relative difference "
            f"{r['max_difference']:.3g} > {CHECK_TOL:g}): not timed"
        )
    if wrong:
        keep = [
            f
            for f in peers
            if not any(r["who"] == f.who and r["variant"] == f.variant and r["kernel"] == f.kernel for r in wrong)
        ]
        exe, rows_kept = harness.build(arm, keep, work / "harness")
        rows = [
            next(r for r in rows if (r["who"], r["variant"], r["kernel"]) == (k["who"], k["variant"], k["kernel"]))
            for k in rows_kept
        ]
    worst = max(r["max_difference"] for r in rows)
    say(
        f"{arm.name}: {len(rows)} functions agree with robotgen's module on {NSETS} states, max relative "
        f"difference {worst:.1e} <= {CHECK_TOL:g}"
    )
    for row, timing in zip(rows, harness.time_rounds(exe, rows, rounds)):
        row.update(timing)
    kernels = []
    for kernel in KERNELS:
        mine = [r for r in rows if r["kernel"] == kernel]
        ours = next(r for r in mine if r["who"] == "robotgen")
        best = {}
        for who in PEERS:
            theirs = [r for r in mine if r["who"] == who]
            if theirs:
                b = min(theirs, key=lambda r: r["ns_min"])
                best[who] = {"variant": b["variant"], "ns": b["ns_min"], "ratio": b["ns_min"] / ours["ns_min"]}
        kernels.append(
            {
                "kernel": kernel,
                "robotgen_ns": ours["ns_min"],
                "best": best,
                "functions": [
                    {
                        k: r[k]
                        for k in ("who", "variant", "ns_min", "ns_median", "iterations", "max_difference", "layout")
                    }
                    for r in mine
                ],
            }
        )
    return {
        "robot": arm.name,
        "urdf": arm.label,
        "tip": arm.tip,
        "nq": arm.nq,
        "locked_joints": arm.locked,
        "damping": arm.damping,
        "max_difference": worst,
        "kernels": kernels,
    }


def ratio_table(robots: list[dict]) -> str:
    """The issue's table: a row per kernel, a column per arm and peer (peer ns / robotgen ns)."""
    columns = [(r, who) for r in robots for who in PEERS]
    head = ["kernel"] + [
        f"{r['robot']} vs {PEERS[who]}{' (best)' if who == 'pinocchio_cg' else ''}" for r, who in columns
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for i, kernel in enumerate(KERNELS):
        cells = [KERNEL_NAMES[kernel]]
        for r, who in columns:
            best = r["kernels"][i]["best"].get(who)
            cells.append(f"{best['ratio']:.2f}" if best else "-")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def detail_table(robots: list[dict]) -> str:
    head = ["robot", "kernel", "who", "variant", "ns", "median ns", "ratio", "max rel diff"]
    lines = [head]
    for r in robots:
        for k in r["kernels"]:
            for f in k["functions"]:
                lines.append(
                    [
                        r["robot"],
                        k["kernel"],
                        f["who"],
                        f["variant"],
                        f"{f['ns_min']:.1f}",
                        f"{f['ns_median']:.1f}",
                        f"{f['ns_min'] / k['robotgen_ns']:.2f}",
                        f"{f['max_difference']:.1e}",
                    ]
                )
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    fmt = lambda row: "  ".join(s.rjust(w) if i > 3 else s.ljust(w) for i, (s, w) in enumerate(zip(row, widths)))  # noqa: E731
    return "\n".join([fmt(lines[0]), fmt(["-" * w for w in widths])] + [fmt(r) for r in lines[1:]])


def below_goals(robots: list[dict]) -> list[str]:
    out = []
    for r in robots:
        for k in r["kernels"]:
            for who, best in k["best"].items():
                goal = GOALS[k["kernel"]]
                if best["ratio"] < goal:
                    out.append(
                        f"{r['robot']} {k['kernel']}: {best['ratio']:.2f}x against {PEERS[who]} "
                        f"{best['variant']} (goal {goal:.0f}x: robotgen's {k['robotgen_ns']:.0f} ns would "
                        f"have to be {goal / best['ratio']:.2f} times faster)"
                    )
    return out


def section(arm_names: list[str], rounds: int, work: Path) -> dict:
    """The whole comparison; the result for results.json."""
    gen, pcg_status = start_pinocchio_cg()
    status = {"pinocchio_cg": pcg_status, "casadi_kin_dyn": {}}
    try:
        status["casadi_kin_dyn"]["version"] = casadi_kin_dyn.version()
    except PeerUnavailable as e:
        status["casadi_kin_dyn"] = {"error": str(e)}
        say(f"casadi_kin_dyn not measured: {e}")
    if "error" in pcg_status:
        say(f"Pinocchio-cg not measured: {pcg_status['error']}")
    built, skipped = [], {}
    for name in arm_names:
        try:
            built.append(arms.build(name, work / "robotgen"))
        except arms.ArmError as e:
            skipped[name] = str(e)
            say(f"{name} not measured: {e}")
    robots = []
    for arm in built:
        peers = peer_functions(arm, gen, status)
        try:
            robots.append(measure(arm, peers, work / arm.name, rounds))
        except HarnessError as e:
            skipped[arm.name] = str(e)
            say(f"{arm.name} not measured: {e}")
    if robots:
        say(
            f"robotgen's kernels vs the code-generating peers, C {' '.join(CFLAGS)} on both sides, least of "
            f"{rounds} interleaved rounds (ns per call)"
        )
        print(detail_table(robots))
        print("\nratio = peer ns / robotgen ns (> 1: robotgen is faster), against each peer's best variant\n")
        print(ratio_table(robots), flush=True)
        short = below_goals(robots)
        if short:
            say("below issue 35's floors (2x, derivatives 3x):\n  " + "\n  ".join(short))
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "c_flags": CFLAGS,
        "rounds": rounds,
        "states": NSETS,
        "check_tolerance": CHECK_TOL,
        "units": "ns per call, least of each harness's 7 repeats over the rounds; ratio = peer ns / robotgen ns",
        "notes": [
            "each kernel's functions are timed in the same program, their repeats interleaved",
            "the peers' models have no joint damping; the check takes robotgen's viscous term out "
            "(its cost, n multiply-adds, stays in robotgen's time)",
            "Pinocchio-cg's crba and minv write M's and M^-1's upper triangle, robotgen the whole matrix",
        ],
        "peers": status,
        "not_measured": skipped,
        "robots": robots,
        "below_goals": below_goals(robots),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", nargs="*", choices=sorted(arms.ARMS), default=list(arms.ARMS))
    ap.add_argument("--rounds", type=int, default=3, help="harness runs per arm (default 3)")
    ap.add_argument("--quick", action="store_true", help="one round")
    ap.add_argument(
        "--json",
        default=str(HERE / "results.json"),
        help="JSON file that gets the results under 'code_generators' (its other keys kept)",
    )
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="robotgen-peers-") as tmp:
        result = section(args.arms, 1 if args.quick else args.rounds, Path(tmp))
    path = Path(args.json)
    data = json.loads(path.read_text()) if path.exists() else {}
    data["code_generators"] = result
    path.write_text(json.dumps(data, indent=2) + "\n")
    say(f"wrote {path}")
    return 0 if result["robots"] else 1


if __name__ == "__main__":
    sys.exit(main())
