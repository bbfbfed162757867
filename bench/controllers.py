"""Benchmark: servo steps and controller cycles in C.

    python bench/controllers.py [--json bench/controllers.json] [--quick]

1. Run-time against folded gains: specs/styx_high_ct.yaml is built twice, as written (kp, kv
   read from the `<name>_params` struct) and with `gains: folded`; the C servo_step of each
   is timed in one harness run, alternating rounds; the ratio runtime / folded is reported.
2. One sampling period of the hand controllers on the PUMA 560 (specs/puma560_rmac.yaml, and
   the same arm under resolved_acceleration): the C controller step (ns per cycle, through
   the controller's C API, state in a caller-owned struct), against the same step kernel
   evaluated by CasADi's own virtual machine (casadi.Function called from C++ would be fairer
   still; here it is called from Python with numpy arguments, measured in the same run and
   reported with the cost of an empty CasADi call subtracted).

3. The servo step of every example tree and the resolved-rate PUMA's steps (rate, position,
   regulator): ns per call in C and the manifest's operation counts, so that regressions show.

Every number is the minimum over repeats (the least disturbed run); gcc -O2, no -march.
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

CFLAGS = ["-std=c99", "-O2"]

SERVO_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "A.h"
#include "B.h"
#define NSETS 64
static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e9 + t.tv_nsec;
}
static unsigned long long s = 88172645463325252ULL;
static double u(void) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(s >> 11) / 9007199254740992.0 - 0.5;
}
static double IN[NSETS][64];
static volatile double sink;
int main(void) {
    double tau[16], state_next[64];
    A_params pa = A_PARAMS_DEFAULT;
    int set, k, round;
    for (set = 0; set < NSETS; ++set) for (k = 0; k < 64; ++k) IN[set][k] = 0.1 * u();
    for (set = 0; set < NSETS; ++set) {  /* near a grasping posture */
        IN[set][0] += 2.04; IN[set][1] += 0.31; IN[set][2] += 1.10; IN[set][3] += 2.83;
    }
    for (round = 0; round < ROUNDS; ++round) {
        double best[2] = {1e30, 1e30};
        int rep;
        for (rep = 0; rep < 10; ++rep) {
            int which;
            for (which = 0; which < 2; ++which) {
                long n = 0, iters = 100000;
                double t0 = now();
                for (n = 0; n < iters; ++n) {
                    const double *x = IN[n & (NSETS - 1)];
                    if (which == 0)
                        A_servo_step(x, x + 4, x + 8, x + 11, x + 14, x + 17, x + 20, x + 24, x + 40, &pa,
                                     tau, state_next);
                    else
                        B_servo_step(x, x + 4, x + 8, x + 11, x + 14, x + 17, x + 20, x + 24, x + 40, tau, state_next);
                    sink += tau[0];
                }
                double ns = (now() - t0) / iters;
                if (ns < best[which]) best[which] = ns;
            }
        }
        printf("%f %f\n", best[0], best[1]);
    }
    return 0;
}
"""


def build(spec: Path, out: Path, name: str | None = None, change=None) -> Path:
    data = yaml.safe_load(spec.read_text())
    if name:
        data["name"] = name
    if change:
        change(data)
    path = out.parent / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    subprocess.run(
        [sys.executable, "-m", "robotgen", "build", str(path), "-o", str(out), "-q"],
        check=True,
        cwd=ROOT,
        capture_output=True,
    )
    return out


def rename(text: str, old: str, new: str) -> str:
    return text.replace(old + "_", new + "_").replace(old.upper() + "_", new.upper() + "_")


def gains_section(tmp: Path, rounds: int) -> dict:
    spec = ROOT / "specs" / "styx_high_ct.yaml"
    a = build(spec, tmp / "A", "bench_runtime")
    b = build(spec, tmp / "B", "bench_folded", lambda d: d["nodes"]["ct_hand"]["control"].update(gains="folded"))
    work = tmp / "gains"
    work.mkdir()
    for src, prefix, dst in ((a, "bench_runtime", "A"), (b, "bench_folded", "B")):
        for ext in (".h", ".c"):
            text = rename((src / f"{prefix}{ext}").read_text(), prefix, dst)
            text = text.replace(f'#include "{prefix}.h"', f'#include "{dst}.h"')
            (work / f"{dst}{ext}").write_text(text)
    (work / "harness.c").write_text(SERVO_HARNESS.replace("ROUNDS", str(rounds)))
    exe = work / "harness"
    subprocess.run(
        [
            "cc",
            *CFLAGS,
            "-I",
            str(work),
            str(work / "harness.c"),
            str(work / "A.c"),
            str(work / "B.c"),
            "-o",
            str(exe),
            "-lm",
        ],
        check=True,
    )
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    values = np.array(out, dtype=float).reshape(-1, 2)
    runtime, folded = values[:, 0].min(), values[:, 1].min()
    ops = {}
    for which, d in (("runtime", a), ("folded", b)):
        manifest = json.loads((d / "manifest.json").read_text())
        ops[which] = next(f["arithmetic_ops"] for f in manifest["functions"] if f["name"] == "servo_step")
    result = {
        "spec": "specs/styx_high_ct.yaml",
        "function": "servo_step",
        "runtime_ns": runtime,
        "folded_ns": folded,
        "ratio": runtime / folded,
        "arithmetic_ops": ops,
        "rounds": rounds,
    }
    print(
        f"bench: styx_high_ct servo_step: run-time gains {runtime:.1f} ns, folded {folded:.1f} ns, "
        f"ratio {runtime / folded:.3f} ({ops['runtime']} vs {ops['folded']} operations)"
    )
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=str(HERE / "controllers.json"))
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="robotgen-bench-ctl-"))
    try:
        rounds = 3 if args.quick else 7
        result = {
            "machine": {"platform": platform.platform(), "processor": platform.processor()},
            "c_flags": CFLAGS,
            "units": "ns per call, min over repeats and rounds",
            "gains": gains_section(tmp, rounds),
            "controllers": controllers_section(tmp, rounds),
            "servo_steps": servo_steps_section(tmp, rounds),
        }
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
        print(f"bench: wrote {args.json}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


CONTROLLER_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <time.h>
#include "M.h"
static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e9 + t.tv_nsec;
}
static volatile double sink;
int main(void) {
    static TYPE c;
    M_params p = M_PARAMS_DEFAULT;
    double q[6] = Q0, qd[6] = {0}, pose[16] = POSE, twist[6] = {0}, accel[6] = {0}, tau[6];
    int round;
    PREFIX_reset(&c);
    for (round = 0; round < ROUNDS; ++round) {
        double best = 1e30;
        int rep;
        for (rep = 0; rep < 10; ++rep) {
            long n, iters = 20000;
            double t0 = now();
            for (n = 0; n < iters; ++n) {
                /* a slowly moving target: the step cannot be specialised to one input */
                pose[3] = POSE_X + 1e-3 * sin(1e-3 * (double)n);
                PREFIX_step(&c, q, qd, pose, twist, accel, &p, tau);
                sink += tau[0];
            }
            double ns = (now() - t0) / iters;
            if (ns < best) best = ns;
        }
        printf("%f\n", best);
    }
    return 0;
}
"""


def controllers_section(tmp: Path, rounds: int) -> list[dict]:
    """One period of each hand controller of the PUMA 560: the C controller step against
    CasADi's evaluator on the same step kernel (called from Python, the cost of an empty
    CasADi call subtracted)."""
    import casadi as ca

    from robotgen.frontend import load_system
    from robotgen.symbolic import controllers_for, kernels_for

    rmac = ROOT / "specs" / "puma560_rmac.yaml"
    variants = [
        ("bench_rmac", None),
        (
            "bench_rac",
            lambda d: d["nodes"]["rmac"]["control"].update(
                law="resolved_acceleration",
                resolved_acceleration=d["nodes"]["rmac"]["control"].pop("resolved_adaptive"),
            ),
        ),
    ]
    rows = []
    empty = ca.Function("empty", [ca.SX.sym("x")], [ca.SX.sym("x") * 0])
    x0 = np.zeros(1)
    t_empty = min(timeit.repeat(lambda: empty(x0), number=2000, repeat=5)) / 2000
    for name, change in variants:
        out = build(rmac, tmp / name, name, change)
        system = load_system(str(tmp / f"{name}.yaml"))
        controller = controllers_for(system)[0]
        kernel = next(k for k in kernels_for(system) if k.name == controller.step)
        prefix = f"{name}_{'adaptive' if 'rmac' in name else 'resolved_acceleration'}_controller"
        q0 = [0, np.pi / 4, np.pi, 0, np.pi / 4, 0]
        sys.path.insert(0, str(out))
        module = __import__(name)
        sys.path.remove(str(out))
        pose = np.asarray(module.fk(np.array(q0)) @ np.asarray(system.root_node.hand.tool))
        harness = (
            CONTROLLER_HARNESS.replace("M_params", f"{name}_params")
            .replace("M_PARAMS_DEFAULT", f"{name.upper()}_PARAMS_DEFAULT")
            .replace('"M.h"', f'"{name}.h"')
            .replace("TYPE", prefix)
            .replace("PREFIX", prefix)
            .replace("ROUNDS", str(rounds))
            .replace("Q0", "{" + ", ".join(map(repr, q0)) + "}")
            .replace("POSE_X", repr(float(pose[0, 3])))
            .replace("POSE", "{" + ", ".join(map(repr, pose.ravel().tolist())) + "}")
        )
        (out / "bench.c").write_text(harness)
        subprocess.run(
            [
                "cc",
                *CFLAGS,
                "-I",
                str(out),
                str(out / "bench.c"),
                str(out / f"{name}.c"),
                "-o",
                str(out / "bench"),
                "-lm",
            ],
            check=True,
        )
        c_ns = min(
            float(v)
            for v in subprocess.run([str(out / "bench")], capture_output=True, text=True, check=True).stdout.split()
        )
        args = [np.array(q0), np.zeros(6), pose.ravel(), np.zeros(6), np.zeros(6)]
        n_in = kernel.function.n_in()
        args += [np.zeros(kernel.function.size1_in(k)) for k in range(len(args), n_in)]
        if controller.init is not None:
            init = next(k for k in kernels_for(system) if k.name == controller.init).function
            args[5] = np.array(init(*args[:5])).ravel()
            args[6] = np.ones(1)
        defaults = [np.array(p.default) for p in (kernel.inputs[-1].parameters if kernel.inputs[-1].parameters else ())]
        if defaults:
            args[-1] = np.concatenate(defaults)
        f = kernel.function
        casadi_s = min(timeit.repeat(lambda f=f, args=args: f(*args), number=200, repeat=5)) / 200
        casadi_ns = (casadi_s - t_empty) * 1e9
        ops = next(
            fn["arithmetic_ops"]
            for fn in json.loads((out / "manifest.json").read_text())["functions"]
            if fn["name"] == controller.step
        )
        rows.append(
            {
                "controller": controller.class_name,
                "spec": "specs/puma560_rmac.yaml" + ("" if change is None else " with law resolved_acceleration"),
                "c_ns": c_ns,
                "casadi_ns": casadi_ns,
                "casadi_empty_call_ns": t_empty * 1e9,
                "ratio_casadi_over_c": casadi_ns / c_ns,
                "step_arithmetic_ops": ops,
            }
        )
        print(
            f"bench: {controller.class_name} (PUMA 560), one period: C {c_ns / 1e3:.2f} us, CasADi evaluator "
            f"{casadi_ns / 1e3:.2f} us (empty call {t_empty * 1e6:.2f} us subtracted): CasADi / C = "
            f"{casadi_ns / c_ns:.1f}; {ops} operations"
        )
    return rows


STEP_HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "NAME.h"
#define NSETS 64
static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e9 + t.tv_nsec;
}
static unsigned long long s = 88172645463325252ULL;
static double u(void) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(s >> 11) / 9007199254740992.0 - 0.5;
}
static double IN[NSETS][TOTAL + 1];
static volatile double sink;
int main(void) {
    PARAMS_DECL
    OUT_DECL
    int set, k, round, failed = 0;
    for (set = 0; set < NSETS; ++set) for (k = 0; k <= TOTAL; ++k) IN[set][k] = u();
    FIXED
    for (set = 0; set < NSETS; ++set) failed += CALL(IN[set]) != 0;
    for (round = 0; round < ROUNDS; ++round) {
        double best = 1e30;
        int rep;
        for (rep = 0; rep < 10; ++rep) {
            long n, iters = 20000;
            double t0 = now();
            for (n = 0; n < iters; ++n) {
                sink += CALL(IN[n & (NSETS - 1)]);
                sink += OUT0[0];
            }
            double ns = (now() - t0) / iters;
            if (ns < best) best = ns;
        }
        printf("%f %d\n", best, failed);
    }
    return 0;
}
"""
STEP_SPECS = ["styx_high_ct", "styx_low_ct", "styx_multilevel", "styx_redundant", "tripod_grasp", "puma560_rmrc"]
STEP_FUNCTIONS = ["servo_step", "rate_step", "position_step", "lqr_step"]
STYX_GRASP = [2.04, 0.31, 1.10, 2.83]  # the Styx fingers' joint angles near a grasp (as in gains_section)


def servo_steps_section(tmp: Path, rounds: int) -> list[dict]:
    """The servo step of every example tree, and the resolved-rate PUMA's steps: ns per call in
    C on random inputs in [-0.5, 0.5] (64 of them, cycled; a step that reports a nonzero status
    has still computed everything), with the operation counts of the manifest."""
    rows = []
    for spec_name in STEP_SPECS:
        out = tmp / f"steps-{spec_name}"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "robotgen",
                "build",
                str(ROOT / "specs" / f"{spec_name}.yaml"),
                "-o",
                str(out),
                "-q",
                "--no-compile",
            ],
            check=True,
            cwd=ROOT,
            capture_output=True,
        )
        manifest = json.loads((out / "manifest.json").read_text())
        for f in manifest["functions"]:
            if f["name"] not in STEP_FUNCTIONS:
                continue
            sizes = [int(np.prod(p["shape"])) for p in f["inputs"]]
            offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int).tolist()
            args = [f"(x) + {o}" for o in offsets] + (["&p"] if f.get("reads_parameters", False) else [])
            args += [f"OUT{k}" for k in range(len(f["outputs"]))]
            outs = " ".join(
                f"static double OUT{k}[{max(1, int(np.prod(p['shape'])))}];" for k, p in enumerate(f["outputs"])
            )
            params = (
                f"{spec_name}_params p = {spec_name.upper()}_PARAMS_DEFAULT;"
                if f.get("reads_parameters", False)
                else ""
            )
            call = f"#define CALL(x) {f['c_name']}({', '.join(args)})"
            # a period, not a random number, where an input is the time step
            fixed = ""
            if spec_name.startswith("styx"):  # near a grasp, not a singular straight finger
                fixed += " for (set = 0; set < NSETS; ++set) for (k = 0; k < TOTAL; ++k) IN[set][k] *= 0.2;"
                fixed += "".join(
                    f" for (set = 0; set < NSETS; ++set) IN[set][{k}] += {x};" for k, x in enumerate(STYX_GRASP)
                )
            # a period, not a random number, where an input is the time step
            fixed += "".join(
                f" for (set = 0; set < NSETS; ++set) IN[set][{o}] = 1e-3;"
                for o, p in zip(offsets, f["inputs"])
                if p["name"] == "dt"
            )
            text = (
                STEP_HARNESS.replace('"NAME.h"', f'"{spec_name}.h"\n{call}')
                .replace("FIXED", fixed)
                .replace("TOTAL", str(sum(sizes)))
                .replace("ROUNDS", str(rounds))
                .replace("PARAMS_DECL", params)
                .replace("OUT_DECL", outs)
            )
            src = out / f"bench_{f['name']}.c"
            src.write_text(text)
            exe = out / f"bench_{f['name']}"
            subprocess.run(
                ["cc", *CFLAGS, "-I", str(out), str(src), str(out / f"{spec_name}.c"), "-o", str(exe), "-lm"],
                check=True,
            )
            lines = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split("\n")
            values = [line.split() for line in lines if line.strip()]
            ns = min(float(v[0]) for v in values)
            failed = int(values[0][1])
            rows.append(
                {
                    "spec": f"specs/{spec_name}.yaml",
                    "function": f["name"],
                    "c_ns": ns,
                    "arithmetic_ops": f["arithmetic_ops"],
                    "sin_cos_ops": f["sin_cos_ops"],
                    "nonzero_status_of_64_inputs": failed,
                }
            )
            note = f"; status != 0 on {failed} of 64 inputs" if failed else ""
            print(
                f"bench: {spec_name} {f['name']}: {ns:8.1f} ns, {f['arithmetic_ops']} operations "
                f"({f['sin_cos_ops']} sin/cos){note}"
            )
    return rows


if __name__ == "__main__":
    sys.exit(main())
