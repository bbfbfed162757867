"""Batches across states: states per second of the generated C's <fn>_batch against a loop of
single calls, on the UR5 and the Panda.

    python bench/batch.py [--quick] [--robots ur5 panda] [--precision double float]
                          [--json bench/batch.json]

For each robot (example-robot-data's URDF, built by robotgen with its derivatives) and each
precision, a C harness written from the module's manifest (compiled -O2 -ffp-contract=off, as
robotgen's own build) fills 1024 random states and times, in interleaved rounds (least of the
rounds, each >= 20 ms):
  loop     for k < 1024: <fn>(state k)                          (the single-state function)
  W lanes  <fn>_batch_lanes(W, 1024, ...) for every width the CPU runs (robotgen.emit.lanes)
for mass, inverse_dynamics, forward_dynamics and their derivatives, after checking that every
width's results equal the loop's bit for bit. Then discrete_dynamics_derivatives over a
100-knot horizon (n = 100, one call of the widest width) as one number: microseconds per
horizon, against the loop's. --quick: the UR5 in double, 5 rounds, no peer.

Then Pinocchio-cg in a loop, in the same run: bench/code_generators.py's harness (its
agreement check first) times the best variant of each kernel that Pinocchio's code generation
has, single calls cycled over its 256 states, and robotgen's single calls beside them; the
table gives the batch's states per second against it (double only: Pinocchio-cg generates
double). If Pinocchio-cg cannot be built here, the bench says why and goes on. --no-peer skips
it.

Prints a table (states per second in millions, the ratio to the loop) and writes
bench/batch.json. The machine may be shared: the rounds are interleaved so that load moves
every column alike, and the least of them is reported.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from run import robots_dir  # noqa: E402  (bench/run.py: example-robot-data's models)

ROBOTS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp"),
}
FUNCTIONS = [
    "mass",
    "inverse_dynamics",
    "forward_dynamics",
    "inverse_dynamics_derivatives",
    "forward_dynamics_derivatives",
    "discrete_dynamics_derivatives",
]
STATES = 1024
HORIZON = 100
CFLAGS = ["-O2", "-std=c99", "-ffp-contract=off"]


def build(robot: str, precision: str, tmp: Path) -> Path:
    from robotgen.cli import main

    urdf, tip = ROBOTS[robot]
    name = f"{robot}_{precision}"
    out = tmp / name
    status = main(
        [
            "build",
            str(robots_dir() / urdf),
            "--tip",
            tip,
            "--name",
            name,
            "-o",
            str(out),
            "--precision",
            precision,
            "--no-compile",
            "--quiet",
        ]
    )
    if status != 0:
        sys.exit(f"bench: robotgen build {urdf} exited with {status}")
    return out


def harness(name: str, real: str, functions: list[dict], rounds: int) -> str:
    """The C of one robot's harness: states, timings, and the bit check, printed as json."""
    lines = [
        "#define _POSIX_C_SOURCE 199309L",
        "#include <stdio.h>",
        "#include <stdlib.h>",
        "#include <string.h>",
        "#include <time.h>",
        f'#include "{name}.h"',
        "static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t);"
        " return t.tv_sec + 1e-9 * t.tv_nsec; }",
        f"static {real} *fill(size_t count, double low, double high) {{",
        f"  {real} *a = malloc(count * sizeof *a); size_t i;",
        f"  for (i = 0; i < count; ++i) a[i] = ({real})(low + (high - low) * (rand() / (double)RAND_MAX));",
        "  return a;",
        "}",
        "int main(void) {",
        f"  int lanes[5] = {{1, {name}_batch_lanes(2), {name}_batch_lanes(4), {name}_batch_lanes(8), "
        f"{name}_batch_lanes(16)}}, w, r, k, reps, first = 1;",
        "  double t, best[6], horizon[2];",
        "  srand(7);",
        '  printf("{\\"widths\\": [");',
        '  for (w = 0; w < 5; ++w) if (w == 0 || lanes[w] != lanes[w - 1]) printf("%s%d", w ? ", " : "", lanes[w]);',
        '  printf("], \\"functions\\": {");',
    ]
    for f in functions:
        args = [p["name"] for p in f["inputs"]]
        sizes = {p["name"]: math.prod(p["shape"]) for p in f["inputs"] + f["outputs"]}
        lines.append("  {")
        for p in f["inputs"]:
            low, high = ("0.001", "0.01") if p["name"] == "dt" else ("-3.0", "3.0")
            lines.append(f"    {real} *{p['name']} = fill({STATES} * {sizes[p['name']]}, {low}, {high});")
        for p in f["outputs"]:
            lines.append(f"    {real} *{p['name']} = malloc({STATES} * {sizes[p['name']]} * sizeof(*{p['name']}));")
            lines.append(f"    {real} *{p['name']}_1 = malloc({STATES} * {sizes[p['name']]} * sizeof(*{p['name']}));")
        outs = [p["name"] for p in f["outputs"]]
        single = ", ".join(
            [f"{a} + (size_t)k * {sizes[a]}" for a in args] + [f"{o}_1 + (size_t)k * {sizes[o]}" for o in outs]
        )

        def batch(n: str, lane: str, o: list[str], fn: str = f["name"], ins: list[str] = args) -> str:
            return f"{name}_{fn}_batch_lanes({lane}, {n}, {', '.join(ins + o)})"

        compare = " || ".join(f"memcmp({o}, {o}_1, {STATES} * {sizes[o]} * sizeof(*{o}))" for o in outs)
        lines += [
            f"    for (k = 0; k < {STATES}; ++k) {name}_{f['name']}({single});",
            "    for (w = 1; w < 5; ++w) {",
            f"      {batch(str(STATES), 'lanes[w]', outs)};",
            f'      if ({compare}) {{ fprintf(stderr, "{f["name"]}: lanes %d differ from single calls\\n", lanes[w]);'
            " return 1; }",
            "    }",
            "    for (w = 0; w < 6; ++w) best[w] = 1e30;",
            "    reps = 1;",
            f"    t = now(); for (k = 0; k < {STATES}; ++k) {name}_{f['name']}({single}); t = now() - t;",
            "    reps = (int)(0.02 / (t > 1e-7 ? t : 1e-7)) + 1;",
            f"    for (r = 0; r < {rounds}; ++r) {{",
            "      int i;",
            f"      t = now(); for (i = 0; i < reps; ++i) for (k = 0; k < {STATES}; ++k) {name}_{f['name']}({single});",
            "      t = (now() - t) / reps; if (t < best[0]) best[0] = t;",
            "      for (w = 1; w < 5; ++w) {",
            "        if (lanes[w] == lanes[w - 1]) continue;",
            f"        t = now(); for (i = 0; i < reps; ++i) {batch(str(STATES), 'lanes[w]', outs)};",
            "        t = (now() - t) / reps; if (t < best[w]) best[w] = t;",
            "      }",
            "    }",
            f'    printf("%s\\"{f["name"]}\\": {{\\"loop_s\\": %.6e, \\"lanes_s\\": {{", first ? "" : ", ", best[0]);',
            "    first = 0;",
            "    for (w = 1, k = 0; w < 5; ++w) if (lanes[w] != lanes[w - 1] && lanes[w] > 1)"
            ' { printf("%s\\"%d\\": %.6e", k ? ", " : "", lanes[w], best[w]); k = 1; }',
            '    printf("}");',
        ]
        if f["name"] == "discrete_dynamics_derivatives":
            lines += [
                "    horizon[0] = horizon[1] = 1e30;",
                f"    for (r = 0; r < {rounds} * 20; ++r) {{",
                f"      t = now(); for (k = 0; k < {HORIZON}; ++k) {name}_{f['name']}({single}); t = now() - t;",
                "      if (t < horizon[0]) horizon[0] = t;",
                f"      t = now(); {batch(str(HORIZON), '0', [o + '_1' for o in outs])}; t = now() - t;",
                "      if (t < horizon[1]) horizon[1] = t;",
                "    }",
                f'    printf(", \\"horizon_{HORIZON}\\": {{\\"loop_s\\": %.6e, \\"batch_s\\": %.6e}}",'
                " horizon[0], horizon[1]);",
            ]
        lines.append('    printf("}");')
        lines += [f"    free({a});" for a in args] + [f"    free({o}); free({o}_1);" for o in outs]
        lines.append("  }")
    lines += ['  printf("}}\\n");', "  return 0;", "}"]
    return "\n".join(lines) + "\n"


def run(out: Path, rounds: int, functions: list[str]) -> dict:
    manifest = json.loads((out / "manifest.json").read_text())
    name, real = manifest["name"], "float" if manifest["precision"] == "float" else "double"
    chosen = [f for f in manifest["functions"] if f["name"] in functions]
    (out / "batch_harness.c").write_text(harness(name, real, chosen, rounds))
    cc = os.environ.get("CC", "cc")
    command = [
        cc,
        *CFLAGS,
        "-I",
        str(out),
        str(out / "batch_harness.c"),
        str(out / f"{name}.c"),
        "-lm",
        "-o",
        str(out / "batch_harness"),
    ]
    subprocess.run(command, check=True)
    result = subprocess.run([str(out / "batch_harness")], capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"bench: {name}: {result.stderr}")
    data = json.loads(result.stdout)
    data["command"] = " ".join(command)
    return data


def pinocchio_cg_loops(robots: list[str], rounds: int, work: Path) -> dict:
    """robot -> kernel -> Pinocchio-cg's best variant in a loop of single calls, with robotgen's
    single calls timed beside it (bench/code_generators.py's harness, after its agreement check);
    {"error": why} when Pinocchio-cg cannot be built here."""
    import code_generators as peers

    gen, status = peers.start_pinocchio_cg()
    if gen is None:
        print(f"bench: Pinocchio-cg not measured: {status['error']}", flush=True)
        return {"error": status["error"]}
    out: dict = {}
    for robot in robots:
        print(f"bench: {robot}: Pinocchio-cg in a loop ...", flush=True)
        chosen = {"pinocchio_cg": dict(status), "casadi_kin_dyn": {"error": "not asked"}}
        try:
            arm = peers.arms.build(robot, work / "robotgen")
            measured = peers.measure(arm, peers.peer_functions(arm, gen, chosen), work / robot, rounds)
        except (peers.arms.ArmError, peers.HarnessError) as e:
            print(f"bench: {robot}: Pinocchio-cg not measured: {e}", flush=True)
            out[robot] = {"error": str(e)}
            continue
        if "error" in chosen["pinocchio_cg"]:
            out[robot] = {"error": chosen["pinocchio_cg"]["error"]}
            continue
        out[robot] = {
            k["kernel"]: {
                "variant": k["best"]["pinocchio_cg"]["variant"],
                "ns": k["best"]["pinocchio_cg"]["ns"],
                "robotgen_ns": k["robotgen_ns"],
            }
            for k in measured["kernels"]
            if "pinocchio_cg" in k["best"] and k["kernel"] in FUNCTIONS
        }
    return out


def table(results: dict, peer: dict | None = None) -> str:
    rows = [
        [
            "robot",
            "precision",
            "function",
            "loop Mstates/s",
            "widest",
            "Mstates/s",
            "x loop",
            "others",
            "Pinocchio-cg loop Mstates/s",
            "x Pinocchio-cg",
        ]
    ]
    for key, data in results.items():
        robot, precision = key.split("/")
        for fn, r in data["functions"].items():
            widths = sorted(r["lanes_s"], key=int)
            if not widths:
                continue
            widest = widths[-1]
            others = ", ".join(f"{w}: {r['loop_s'] / r['lanes_s'][w]:.2f}x" for w in widths[:-1])
            theirs = (peer or {}).get(robot, {}).get(fn) if precision == "double" else None
            rate = STATES / r["lanes_s"][widest]
            rows.append(
                [
                    robot,
                    precision,
                    fn,
                    f"{STATES / r['loop_s'] / 1e6:.2f}",
                    widest,
                    f"{rate / 1e6:.2f}",
                    f"{r['loop_s'] / r['lanes_s'][widest]:.2f}",
                    others,
                    f"{1e3 / theirs['ns']:.2f} ({theirs['variant']})" if theirs else "",
                    f"{rate * theirs['ns'] * 1e-9:.2f}" if theirs else "",
                ]
            )
            if "horizon_100" in r:
                h = r["horizon_100"]
                rows.append(
                    [
                        robot,
                        precision,
                        f"{fn}, {HORIZON}-knot horizon",
                        f"{h['loop_s'] * 1e6:.1f} us",
                        "widest",
                        f"{h['batch_s'] * 1e6:.1f} us",
                        f"{h['loop_s'] / h['batch_s']:.2f}",
                        "",
                        "",
                        "",
                    ]
                )
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=["ur5", "panda"])
    parser.add_argument("--precision", nargs="+", choices=["double", "float"], default=["double", "float"])
    parser.add_argument("--functions", nargs="+", choices=FUNCTIONS, default=FUNCTIONS)
    parser.add_argument("--json", type=Path, default=HERE / "batch.json")
    parser.add_argument("--no-peer", action="store_true", help="no Pinocchio-cg loop")
    args = parser.parse_args()
    robots, precisions, rounds, peer_runs = args.robots, args.precision, 15, 3
    if args.quick:
        robots, precisions, rounds, peer_runs = ["ur5"], ["double"], 5, 0
    if args.no_peer or "double" not in precisions:
        peer_runs = 0
    results: dict = {}
    peer: dict = {}
    with tempfile.TemporaryDirectory(prefix="robotgen-batch-") as tmp:
        for robot in robots:
            for precision in precisions:
                print(f"bench: {robot} ({precision}): building and timing ...", flush=True)
                results[f"{robot}/{precision}"] = run(build(robot, precision, Path(tmp)), rounds, args.functions)
        if peer_runs:
            peer = pinocchio_cg_loops(robots, peer_runs, Path(tmp) / "peers")
    print(table(results, peer))
    args.json.write_text(
        json.dumps(
            {
                "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "machine": platform.processor() or platform.machine(),
                "cpus": os.cpu_count(),
                "states": STATES,
                "horizon": HORIZON,
                "results": results,
                "pinocchio_cg_loop": peer,
            },
            indent=2,
            sort_keys=True,
        )
        + "\n"
    )


if __name__ == "__main__":
    main()
