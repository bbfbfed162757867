"""One C harness per arm: robotgen's kernels and the peers' generated functions in one program
(peer_harness.c and a table calls.c written here), compiled with the kernels' flags; the
agreement check on its 256 states; interleaved timing rounds.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
from run import fresh_copy, kernel_sources  # bench/run.py: a fresh copy per round; the files that hold kernels

from .arms import Arm
from .pinocchio_cg import CACHE, PeerFunction

HERE = Path(__file__).resolve().parent
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off"]  # robotgen's kernels' flags (the extension's build)
NSETS = 256
CHECK_TOL = 1e-9
KERNELS = [
    "mass",
    "inverse_dynamics",
    "forward_dynamics",
    "mass_inverse",
    "inverse_dynamics_derivatives",
    "forward_dynamics_derivatives",
]
ROBOTGEN_OUTPUTS = {
    "mass": (1, [1]),
    "inverse_dynamics": (3, [0]),
    "forward_dynamics": (3, [0]),
    "mass_inverse": (1, [1]),
    "inverse_dynamics_derivatives": (3, [1, 1]),
    "forward_dynamics_derivatives": (3, [1, 1, 1]),
}  # inputs; outputs (1: n x n, 0: n)


class HarnessError(Exception):
    """The harness cannot be built or run, or a function disagrees with robotgen."""


# --- what each function's outputs hold, from robotgen's module -------------------------------


def reference(arm: Arm, x: np.ndarray) -> dict[str, np.ndarray]:
    """Every layout's values on the packed states X (NSETS x 3n), from robotgen's module.
    The peers' models have no joint damping D: their tau is robotgen's less D qd, their forward
    dynamics at tau is robotgen's at tau + D qd (and so are its derivatives in q and M^-1),
    with d ddq / d qd = robotgen's + M^-1 D. Pinocchio's computeRNEADerivatives fills the upper
    triangle of dtau/da = M (its lower triangle zeros)."""
    m, n = arm.module, arm.nq
    q, qd, u = x[:, :n], x[:, n : 2 * n], x[:, 2 * n :]
    d = np.asarray(arm.damping)
    mass = m.mass(q)
    minv = m.mass_inverse(q)
    dtau_dq, dtau_dv = m.inverse_dynamics_derivatives(q, qd, u)
    dtau_dv = dtau_dv - np.diag(d)
    ddq_dq, ddq_dv, ddq_du = m.forward_dynamics_derivatives(q, qd, u + d * qd)
    ddq_dv = ddq_dv + ddq_du * d  # M^-1 D: column j of M^-1 times d_j
    upper = np.triu_indices(n)
    flat = lambda *blocks: np.concatenate([b.reshape(len(x), -1) for b in blocks], axis=1)  # noqa: E731
    return {
        "mass": flat(mass),
        "mass_upper": mass[:, upper[0], upper[1]],
        "mass_inverse": flat(minv),
        "mass_inverse_upper": minv[:, upper[0], upper[1]],
        "tau": m.inverse_dynamics(q, qd, u) - d * qd,
        "ddq": m.forward_dynamics(q, qd, u + d * qd),
        "dtau_dq_dv": flat(dtau_dq, dtau_dv),
        "dtau_dq_dv_da": flat(dtau_dq, dtau_dv, np.triu(mass)),
        "rnea_jacobian": flat(np.concatenate([dtau_dq, dtau_dv, mass], axis=2)),
        "dddq": flat(ddq_dq, ddq_dv, ddq_du),
        "aba_jacobian": flat(np.concatenate([ddq_dq, ddq_dv, ddq_du], axis=2)),
    }


def robotgen_outputs(arm: Arm, kernel: str, x: np.ndarray) -> np.ndarray:
    """robotgen's kernel on the packed states, as its C writes them (damping included)."""
    n = arm.nq
    k = ROBOTGEN_OUTPUTS[kernel][0]
    res = getattr(arm.module, kernel)(*[x[:, i * n : (i + 1) * n] for i in range(k)])
    res = res if isinstance(res, tuple) else (res,)
    return np.concatenate([np.reshape(r, (len(x), -1)) for r in res], axis=1)


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| over max(1, max |b|): run.py's measure, over all states at once."""
    return float(np.abs(a - b).max() / max(1.0, float(np.abs(b).max())))


# --- calls.c ---------------------------------------------------------------------------------


def _robotgen_call(arm: Arm, kernel: str) -> tuple[str, int]:
    n = arm.nq
    k, outs = ROBOTGEN_OUTPUTS[kernel]
    args = [f"x + {i * n}" for i in range(k)]
    offset, ptrs = 0, []
    for o in outs:
        ptrs.append(f"out + {offset}")
        offset += n * n if o else n
    body = f"{arm.name}_{kernel}({', '.join(args + ptrs)});"
    return body, offset


def _peer_call(f: PeerFunction, n: int) -> str:
    if f.convention == "cppadcg":
        return f"const double *in[1] = {{x}};\n    double *o[1] = {{out}};\n    {f.symbol}(in, o, rg_no_atomics);"
    sz_arg, sz_res, sz_iw, sz_w = f.work
    lines = [
        f"static const double *arg[{max(sz_arg, 1)}];",
        f"static double *res[{max(sz_res, 1)}];",
        f"static long long int iw[{max(sz_iw, 1)}];",
        f"static double w[{max(sz_w, 1)}];",
    ]
    lines += [f"arg[{i}] = x + {i * n};" for i in range(f.inputs)]
    offset = 0
    for i, size in enumerate(f.out_sizes):
        lines.append(f"res[{i}] = out + {offset};")
        offset += size
    lines.append(f"{f.symbol}(arg, res, iw, w, 0);")
    return "\n    ".join(lines)


def calls_source(arm: Arm, peers: list[PeerFunction]) -> tuple[str, list[dict]]:
    """calls.c for ARM: robotgen's kernels first, then every peer function; and the table's rows."""
    n = arm.nq
    head = [
        f"/* written by bench/peers/harness.py for {arm.name}: robotgen and its peers, called alike */",
        "#include <stddef.h>",
        '#include "peer_harness.h"',
        f'#include "{arm.name}.h"',
        "",
        "/* CppADCodeGen's calling convention (its generated sources declare the same) */",
        "typedef struct Array { void *data; unsigned long size; int sparse; const unsigned long *idx;"
        " unsigned long nnz; } Array;",
        "struct LangCAtomicFun { void *libModel;",
        "    int (*forward)(void *libModel, int atomicIndex, int q, int p, const Array tx[], Array *ty);",
        "    int (*reverse)(void *libModel, int atomicIndex, int p, const Array tx[], Array *px, const Array py[]); };",
        "static const struct LangCAtomicFun rg_no_atomics = {NULL, NULL, NULL};",
        "",
    ]
    declared = set()
    bodies, rows = [], []
    for kernel in KERNELS:
        body, outputs = _robotgen_call(arm, kernel)
        rows.append(
            {"kernel": kernel, "who": "robotgen", "variant": kernel, "outputs": outputs, "layout": f"robotgen:{kernel}"}
        )
        bodies.append((f"rg_{kernel}", body))
    for i, f in enumerate(peers):
        if f.symbol not in declared:
            declared.add(f.symbol)
            if f.convention == "cppadcg":
                head.append(f"void {f.symbol}(double const *const *in, double *const *out, struct LangCAtomicFun a);")
            else:
                head.append(f"int {f.symbol}(const double **arg, double **res, long long int *iw, double *w, int mem);")
        rows.append({"kernel": f.kernel, "who": f.who, "variant": f.variant, "outputs": f.outputs, "layout": f.layout})
        bodies.append((f"peer_{i}", _peer_call(f, n)))
    text = head + [""]
    for name, body in bodies:
        text += [f"static void {name}(const double *x, double *out) {{", f"    {body}", "}", ""]
    text.append("const struct peer_entry PEER_ENTRIES[] = {")
    for (name, _), row in zip(bodies, rows):
        text.append(f'    {{"{row["kernel"]}", "{row["who"]}", "{row["variant"]}", {name}, {row["outputs"]}}},')
    text += ["};", f"const int PEER_ENTRIES_COUNT = {len(rows)};", ""]
    return "\n".join(text), rows


# --- compiling -------------------------------------------------------------------------------


def compiler() -> tuple[str, str]:
    cc = os.environ.get("CC", "cc")
    try:
        return cc, subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    except (OSError, IndexError) as e:
        raise HarnessError(f"C compiler {cc!r} cannot be run: {e}") from None


def compile_object(source: Path, flags: list[str], includes: list[Path]) -> Path:
    """SOURCE compiled with FLAGS, cached in bench/out/peers/obj/ by its text, flags and compiler
    (a peer's largest generated file takes minutes at -O2)."""
    cc, version = compiler()
    inc = [f"-I{d}" for d in includes]
    headers = "".join(p.read_text() for d in includes for p in sorted(d.glob("*.h")))
    key = hashlib.sha256("\0".join([source.read_text(), headers, version, *flags]).encode()).hexdigest()[:20]
    obj = CACHE / "obj" / f"{source.stem}-{key}.o"
    if not obj.exists():
        obj.parent.mkdir(parents=True, exist_ok=True)
        tmp = obj.with_suffix(f".{os.getpid()}.tmp")
        res = subprocess.run([cc, *flags, *inc, "-c", str(source), "-o", str(tmp)], capture_output=True, text=True)
        if res.returncode != 0:
            raise HarnessError(f"{cc} {' '.join(flags)} -c {source} failed:\n{res.stderr[-2000:]}")
        tmp.replace(obj)
    return obj


def build(arm: Arm, peers: list[PeerFunction], work: Path, flags: list[str] = CFLAGS) -> tuple[Path, list[dict]]:
    """The harness for ARM and PEERS in WORK: its program and its table's rows."""
    cc, _ = compiler()
    work.mkdir(parents=True, exist_ok=True)
    text, rows = calls_source(arm, peers)
    calls = work / "calls.c"
    calls.write_text(text)
    shutil.copy2(HERE / "peer_harness.h", work / "peer_harness.h")
    objects = [
        compile_object(HERE / "peer_harness.c", [*flags, f"-DRG_NQ={arm.nq}"], [work]),
        compile_object(calls, flags, [work, arm.out]),
    ]
    objects += [compile_object(src, flags, [arm.out]) for src in kernel_sources(arm.out)]
    objects += [compile_object(src, flags, []) for src in sorted({f.source for f in peers})]
    exe = work / "peer_harness"
    res = subprocess.run([cc, *flags, *map(str, objects), "-lm", "-o", str(exe)], capture_output=True, text=True)
    if res.returncode != 0:
        raise HarnessError(f"linking {exe} failed:\n{res.stderr[-2000:]}")
    return exe, rows


def check(arm: Arm, exe: Path, rows: list[dict]) -> list[float]:
    """Every entry's outputs on the harness's states against robotgen's module: the relative
    difference of each row (over all states). The caller times only rows within CHECK_TOL."""
    dump = exe.with_name("outputs.bin")
    res = subprocess.run([str(exe), "dump", str(dump)], capture_output=True, text=True)
    if res.returncode != 0:
        raise HarnessError(f"{exe} dump failed: {res.stderr.strip()}")
    data = np.fromfile(dump, dtype=np.float64)
    n = arm.nq
    x = data[: NSETS * 3 * n].reshape(NSETS, 3 * n)
    at = NSETS * 3 * n
    ref = reference(arm, x)
    differences = []
    for row in rows:
        got = data[at : at + NSETS * row["outputs"]].reshape(NSETS, row["outputs"])
        at += NSETS * row["outputs"]
        layout = row["layout"]
        want = robotgen_outputs(arm, row["kernel"], x) if layout.startswith("robotgen:") else ref[layout]
        differences.append(relative_difference(got, want) if got.shape == want.shape else float("inf"))
    return differences


def time_rounds(exe: Path, rows: list[dict], rounds: int, kernels: list[str] | None = None) -> list[dict]:
    """ROUNDS runs of the harness (on KERNELS, default all), each from a fresh copy (bench/run.py's
    fresh_copy); each row's record from the run with its least time."""
    best: dict[tuple[str, str, str], dict] = {}
    rows = [r for r in rows if kernels is None or r["kernel"] in kernels]
    for _ in range(rounds):
        copy = fresh_copy(exe, exe.parent / "round")
        res = subprocess.run([str(copy), *(kernels or [])], capture_output=True, text=True)
        if res.returncode != 0:
            raise HarnessError(f"{exe} failed (exit {res.returncode}): {res.stderr.strip()}")
        for line in res.stdout.splitlines():
            kernel, who, variant, ns_min, ns_median, iters = line.split()
            key = (kernel, who, variant)
            if key not in best or float(ns_min) < best[key]["ns_min"]:
                best[key] = {"ns_min": float(ns_min), "ns_median": float(ns_median), "iterations": int(iters)}
    return [best[(r["kernel"], r["who"], r["variant"])] for r in rows]
