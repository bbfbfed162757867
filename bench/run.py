"""Benchmark: ns per call of the generated C, the generated Python module, and CasADi; and the
generated C against Pinocchio's C++ on real URDF arms.

    python bench/run.py [--spec specs/puma560.yaml] [--out DIR] [--quick] [--json bench/results.json]
                        [--urdf ur5 panda] [--pinocchio-headers]

1. builds the spec with `robotgen build SPEC -o DIR` (a temporary directory unless --out);
2. (a) compiles bench/harness.c against the generated header and kernel sources with
       `cc -std=c99 -O2` (no -march=native: portable numbers) and runs it: calls back to
       back (the core overlaps consecutive calls), then one call at a time (as a Python
       call makes it; the Python overhead is taken over this);
   (b) times the Python extension with timeit: one state per call as a servo loop writes it (y = f(q, qd)),
       the same writing into out= arrays, and a batch of B states in one call (per state);
   (c) times CasADi's own evaluation of the same graph (robotgen.symbolic.kernels_for ->
       Kernel.function): one call with a numpy argument, and Function.map over B states;
   (d) two more rounds of (a)'s one-call timing and (b)'s single calls, alternating: each
       keeps its least disturbed time, so that Python's cost over C, a difference of two
       small times, is not the difference of two moments of a busy machine;
3. prints a table and writes bench/results.json.

Then, for each URDF arm (default UR5 and Panda; none when --spec is given, unless --urdf):
4. builds it with `robotgen build URDF --tip TIP --name NAME -o DIR` (Panda's two finger joints
   are locked at 0 by robotgen; Pinocchio's model gets them locked with buildReducedModel);
5. checks once, before any timing, that the generated module, Pinocchio's Python bindings and
   the C++ harness agree to 1e-9 (relative) on one random state -- a mismatch stops the bench;
6. times bench/harness.c on the generated C and bench/pinocchio_harness.cpp (g++ -O2, linked
   against the pin wheel's libpinocchio_default/_parsers, headers from the cmeel packages) on
   the same input states, in alternating rounds, and prints ns per call, the ratio
   Pinocchio / robotgen (> 1: the generated C is faster) and the generated kernels' op counts,
   the derivatives of inverse and forward dynamics included (computeRNEADerivatives,
   computeABADerivatives).
7. times the fused servo terms against the four separate calls and Pinocchio's three;
8. (not with --quick) times each URDF arm's kernels built with -march=native against the
   portable build: the same bits (-ffp-contract=off keeps a * b + c unfused), what this CPU's wider
   instructions buy.
The compiled Pinocchio harness is cached in bench/out/ (its compile takes ~35 s).

Inputs are random states (angles in [-pi, pi], rates in [-2, 2]); every number is the
minimum over several repeats (the least disturbed run), the C harness also reports the median.
Each run of a harness is from a fresh copy of its program (and of libpinocchio_default), so
that rounds are independent samples (fresh_copy).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import importlib
import json
import math
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
ARITY = {
    "mass": 1,
    "jacobian": 1,
    "gravity": 1,
    "fk": 1,
    "coriolis": 2,
    "nonlinear": 2,
    "jacobian_dot_qd": 2,
    "inverse_dynamics": 3,
    "forward_dynamics": 3,
}
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


def harness_command(out: Path, name: str, nq: int, exe: Path, flags: list[str] = CFLAGS) -> list[str]:
    """The command that compiles bench/harness.c against the generated kernels in OUT into EXE."""
    derivatives = any(
        f["name"] == "inverse_dynamics_derivatives"
        for f in json.loads((out / "manifest.json").read_text())["functions"]
    )
    return [
        os.environ.get("CC", "cc"),
        *flags,
        f'-DRG_HEADER="{name}.h"',
        f"-DRG_PREFIX={name}",
        f"-DRG_NQ={nq}",
        *(["-DRG_DERIVATIVES"] if derivatives else []),
        f"-I{out}",
        str(HERE / "harness.c"),
        *map(str, kernel_sources(out)),
        "-lm",
        "-o",
        str(exe),
    ]


def c_harness(out: Path, name: str, nq: int, work: Path, flags: list[str] = CFLAGS) -> tuple[Path, list[str]]:
    """bench/harness.c compiled against the generated kernels in OUT (once per work directory)."""
    exe = work / "harness"
    cmd = harness_command(out, name, nq, exe, flags)
    if not exe.exists():  # a work directory holds one build (run again in later rounds)
        work.mkdir(parents=True, exist_ok=True)
        subprocess.run(cmd, check=True)
    return exe, cmd


def fresh_copy(path: Path, directory: Path) -> Path:
    """A new copy of ``path`` in ``directory`` (the last one replaced), for one round of timing.
    On this VM a program's code sometimes ran 1.6-3x slower for minutes, run after run, while a
    byte-identical copy under another name ran at full speed: rounds run from one file are not
    independent samples. Each round runs its own copy."""
    directory.mkdir(parents=True, exist_ok=True)
    copy = directory / path.name
    copy.unlink(missing_ok=True)
    shutil.copy2(path, copy)
    return copy


def run_c(
    out: Path,
    name: str,
    nq: int,
    functions: list[str],
    work: Path,
    single_calls: bool = False,
    back_to_back: bool = True,
    flags: list[str] = CFLAGS,
) -> dict:
    """Each function back to back (throughput: the core overlaps consecutive calls), and with
    single_calls also one call at a time (the harness's serial mode: a single call's time, as
    a Python call makes it)."""
    cc = os.environ.get("CC", "cc")
    exe, cmd = c_harness(out, name, nq, work, flags)
    exe = fresh_copy(exe, work / "round")
    results: dict = {}
    for mode in ("",) * back_to_back + ("serial",) * single_calls:
        res = subprocess.run(
            [str(exe), *([mode] if mode else []), *functions], check=True, capture_output=True, text=True
        )
        for line in res.stdout.splitlines():
            fn, ns_min, ns_med, iters = line.split()
            if mode:
                results.setdefault(fn, {}).update(ns_single_call=float(ns_min), ns_single_call_median=float(ns_med))
            else:
                results[fn] = {"ns_min": float(ns_min), "ns_median": float(ns_med), "iterations": int(iters)}
    return {
        "compiler": subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0],
        "cflags": flags,
        "command": " ".join(cmd),
        "results": results,
    }


def calibrate(out: Path, name: str, nq: int, work: Path, rounds: int = 3) -> dict:
    """This machine's scalar peak (operations per ns) and the cost of a libm sin/cos pair, both
    measured by the harness (its calibrate mode) with the flags of the kernels: the least
    disturbed of ``rounds`` runs (the highest peak, the cheapest pair), so that a disturbed
    calibration cannot raise the floors."""
    exe, _ = c_harness(out, name, nq, work)
    runs = []
    for _ in range(rounds):
        res = subprocess.run(
            [str(fresh_copy(exe, work / "round")), "calibrate"], check=True, capture_output=True, text=True
        )
        runs.append({key: float(value) for key, value in (line.split() for line in res.stdout.splitlines())})
    return {"peak_ops_per_ns": max(r["peak_ops_per_ns"] for r in runs), "sincos_ns": min(r["sincos_ns"] for r in runs)}


def floor_ns(ops: int, sin_cos: int, machine: dict) -> float:
    """A kernel's floor: its operations other than sin/cos at the scalar peak, plus its sin/cos
    pairs at libm's cost."""
    return (ops - sin_cos) / machine["peak_ops_per_ns"] + sin_cos / 2 * machine["sincos_ns"]


def best_ns(stmt, number: int, repeat: int) -> float:
    """ns per run of stmt (a callable or a timeit.Timer), the least disturbed of repeat runs."""
    timer = stmt if isinstance(stmt, timeit.Timer) else timeit.Timer(stmt)
    return min(timer.repeat(number=number, repeat=repeat)) / number * 1e9


def states(nq: int, n: int, rng) -> list[np.ndarray]:
    return [rng.uniform(-np.pi, np.pi, (n, nq)), rng.uniform(-2, 2, (n, nq)), rng.uniform(-2, 2, (n, nq))]


def run_python(module, fn: str, nq: int, quick: bool) -> dict:
    f = getattr(module, fn)
    rng = np.random.default_rng(0)
    batch = states(nq, BATCH, rng)[: ARITY[fn]]
    per_state = best_ns(lambda: f(*batch), 5 if quick else 50, 3 if quick else 7) / BATCH
    return {**python_single_calls(module, fn, nq, quick), "ns_per_state_batch": per_state}


def python_single_calls(module, fn: str, nq: int, quick: bool) -> dict:
    """One call as a servo loop writes it, y = f(q, qd) (y holds the previous result while the
    call runs) and f(q, qd, out=r); timeit compiles the statements."""
    f = getattr(module, fn)
    k = ARITY[fn]
    one = [a[0] for a in states(nq, 1, np.random.default_rng(0))][:k]
    number = 2000 if quick else 20000
    names = {f"a{i}": a for i, a in enumerate(one)} | {"f": f, "r": f(*one), "y": None}
    call = f"f({', '.join(f'a{i}' for i in range(k))}"
    return {
        "ns_single": best_ns(timeit.Timer("y = " + call + ")", globals=names), number, 3 if quick else 7),
        "ns_single_out": best_ns(timeit.Timer(call + ", out=r)", globals=names), number, 3 if quick else 7),
    }


def single_call_rounds(
    rows: list[dict], module, out: Path, name: str, nq: int, work: Path, rounds: int, quick: bool
) -> None:
    """Python's cost over C is a difference of two small times taken at different moments on
    a shared machine: further rounds alternate the C harness (serial) and the Python calls,
    and each keeps its least disturbed time (the first round is in ``rows`` already)."""
    functions = [r["function"] for r in rows]
    for _ in range(rounds - 1):
        c = run_c(out, name, nq, functions, work, single_calls=True, back_to_back=False)["results"]
        for r in rows:
            fn = r["function"]
            r["c"]["ns_single_call"] = min(r["c"]["ns_single_call"], c[fn]["ns_single_call"])
            python = python_single_calls(module, fn, nq, quick)
            for key in ("ns_single", "ns_single_out"):
                r["python"][key] = min(r["python"][key], python[key])
    for r in rows:
        r["c"]["single_call_rounds"] = r["python"]["single_call_rounds"] = rounds


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
    head = [
        "function",
        "C ns",
        "C 1 call",
        "Py ns",
        "Py out=",
        "Py-C 1 call",
        "Py out=-C 1 call",
        "Py batch ns/st",
        "CasADi ns",
        "CasADi map ns/st",
        "Py/C",
        "CasADi/C",
        "CasADi/Py",
        "CasADi map/Py batch",
    ]
    lines = [head]
    for r in rows:
        c, p, k = r["c"]["ns_min"], r["python"], r["casadi"]
        one = r["c"]["ns_single_call"]
        lines.append(
            [
                r["function"],
                f"{c:.1f}",
                f"{one:.1f}",
                f"{p['ns_single']:.0f}",
                f"{p['ns_single_out']:.0f}",
                f"{p['ns_single'] - one:.0f}",
                f"{p['ns_single_out'] - one:.0f}",
                f"{p['ns_per_state_batch']:.1f}",
                f"{k['ns_single']:.0f}",
                f"{k['ns_per_state_map']:.1f}",
                f"{p['ns_single'] / c:.1f}",
                f"{k['ns_single'] / c:.1f}",
                f"{k['ns_single'] / p['ns_single']:.1f}",
                f"{k['ns_per_state_map'] / p['ns_per_state_batch']:.1f}",
            ]
        )
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    fmt = lambda row: "  ".join(s.rjust(w) if i else s.ljust(w) for i, (s, w) in enumerate(zip(row, widths)))  # noqa: E731
    return "\n".join([fmt(lines[0]), fmt(["-" * w for w in widths])] + [fmt(r) for r in lines[1:]])


# --- robotgen's generated C against Pinocchio's C++ on URDF arms ---------------------------

URDF_ROBOTS = {  # name: (file under example-robot-data's robots/, tip frame)
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp"),
}
PIN_CALLS = {  # robotgen function -> the Pinocchio call timed by bench/pinocchio_harness.cpp
    "mass": "crba (upper triangle, as returned)",
    "inverse_dynamics": "rnea",
    "gravity": "computeGeneralizedGravity",
    "jacobian": "computeFrameJacobian LOCAL_WORLD_ALIGNED (with its forward kinematics)",
    "coriolis": "computeCoriolisMatrix",
    "forward_dynamics": "aba",
    "inverse_dynamics_derivatives": "computeRNEADerivatives (dtau_dq, dtau_dv)",
    "forward_dynamics_derivatives": "computeABADerivatives (ddq_dq, ddq_dv, Minv upper triangle)",
}
PIN_FUNCTIONS = [
    "mass",
    "inverse_dynamics",
    "gravity",
    "jacobian",
    "coriolis",
    "forward_dynamics",
    "inverse_dynamics_derivatives",
    "forward_dynamics_derivatives",
]
CXX_FLAGS = ["-std=c++17", "-O2", "-DNDEBUG"]
CHECK_TOL = 1e-9


class ToolchainError(Exception):
    """Pinocchio's C++ side cannot be built here; the message says exactly why."""


def cmeel_prefix() -> Path:
    """site-packages/cmeel.prefix of the pin wheel (headers in include/, libraries in lib/)."""
    candidates = []
    try:
        import pinocchio

        candidates += [p for p in Path(pinocchio.__file__).resolve().parents if p.name == "cmeel.prefix"]
    except ImportError:
        pass
    candidates += [Path(sp) / "cmeel.prefix" for sp in site.getsitepackages() + [site.getusersitepackages()]]
    for prefix in candidates:
        if (prefix / "include" / "pinocchio").is_dir() and (prefix / "lib").is_dir():
            return prefix
    raise ToolchainError(
        "no cmeel.prefix with include/pinocchio: the pin wheel is not installed (pip install pin==4.1.0)"
    )


def robots_dir() -> Path:
    """example-robot-data ships only model files, under site-packages/cmeel.prefix/."""
    for sp in site.getsitepackages() + [site.getusersitepackages()]:
        d = Path(sp) / "cmeel.prefix/share/example-robot-data/robots"
        if d.is_dir():
            return d
    sys.exit("bench: example-robot-data is not installed (pip install example-robot-data)")


def pinocchio_toolchain(prefix: Path) -> dict:
    """Include directories, macros and libraries for compiling against the pin wheel, as its
    CMake targets (lib/cmake/pinocchio/pinocchioTargets.cmake) would give them."""
    inc = prefix / "include"
    eigen = next((d for d in [inc / "eigen3", Path("/usr/include/eigen3")] if (d / "Eigen" / "Core").is_file()), None)
    if eigen is None:
        raise ToolchainError(
            f"Eigen headers not found (looked in {inc / 'eigen3'} and /usr/include/eigen3); "
            "the pin wheel does not ship them: pip install cmeel-eigen==3.4.1"
        )
    urdf_headers = next(
        (d for d in [inc / "urdfdom_headers", inc, Path("/usr/include")] if (d / "urdf_model" / "model.h").is_file()),
        None,
    )
    if urdf_headers is None:
        raise ToolchainError(
            f"urdf_model/model.h not found (looked in {inc / 'urdfdom_headers'}); "
            "pinocchio/parsers/urdf.hpp needs it: pip install cmeel-urdfdom-headers==3.0.0"
        )
    libdir = prefix / "lib"
    libs = [n for n in ("pinocchio_parsers", "pinocchio_default") if (libdir / f"lib{n}.so").exists()]
    if "pinocchio_default" not in libs:
        raise ToolchainError(f"no libpinocchio_default.so in {libdir}")
    targets = libdir / "cmake" / "pinocchio" / "pinocchioTargets.cmake"
    text = targets.read_text() if targets.is_file() else ""
    version = re.search(
        r"PINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=(\d+);PINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=(\d+);"
        r"PINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=(\d+)",
        text,
    )
    major, minor, patch = version.groups() if version else ("3", "0", "0")
    defines = [  # pinocchio_headers, pinocchio_default and pinocchio_parsers' interface definitions
        "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
        "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
        "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
        "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
        "-DPINOCCHIO_WITH_URDFDOM",
        f"-DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION={major}",
        f"-DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION={minor}",
        f"-DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION={patch}",
    ]
    return {
        "prefix": prefix,
        "includes": [f"-I{inc}", f"-I{urdf_headers}", f"-I{eigen}"],
        "defines": defines,
        "libs": [f"-L{libdir}", f"-Wl,-rpath,{libdir}", *(f"-l{n}" for n in libs)],
        "eigen": str(eigen),
        "urdf_headers": str(urdf_headers),
    }


class PinocchioHarness:
    """Compiles bench/pinocchio_harness.cpp (in the background, cached in bench/out/)."""

    def __init__(self, headers: bool):
        self.cxx = os.environ.get("CXX", "g++")
        self.tool = pinocchio_toolchain(cmeel_prefix())
        mode = [] if headers else ["-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"]
        self.instantiation = "header" if headers else "library"
        src = HERE / "pinocchio_harness.cpp"
        try:
            version = (
                subprocess.run([self.cxx, "--version"], capture_output=True, text=True).stdout.splitlines()
                or [self.cxx]
            )[0]
        except OSError as e:
            raise ToolchainError(f"C++ compiler {self.cxx!r} cannot be run: {e}") from None
        lib = self.tool["prefix"] / "lib" / "libpinocchio_default.so"
        self.flags = [*CXX_FLAGS, *mode]
        cmd_tail = [*self.tool["defines"], *self.tool["includes"], str(src), *self.tool["libs"]]
        key = hashlib.sha256(
            "\0".join(
                [src.read_text(), version, str(lib.resolve()), str(lib.stat().st_size), *self.flags, *cmd_tail]
            ).encode()
        ).hexdigest()[:16]
        cache = HERE / "out"
        cache.mkdir(exist_ok=True)
        self.exe = cache / f"pinocchio_harness-{self.instantiation}-{key}"
        self.compiler = version
        self.command = [self.cxx, *self.flags, *cmd_tail, "-o", str(self.exe)]
        self.cached = self.exe.exists()
        self._rounds = tempfile.TemporaryDirectory(prefix="robotgen-bench-pinocchio-")
        self._proc = None
        if not self.cached:
            self._tmp = self.exe.with_name(self.exe.name + ".tmp")
            self._proc = subprocess.Popen(
                [*self.command[:-1], str(self._tmp)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
            )

    def wait(self) -> Path:
        if self._proc is not None:
            log, _ = self._proc.communicate()
            if self._proc.returncode != 0:
                errors = [ln for ln in log.splitlines() if "error" in ln] or log.splitlines()[-20:]
                raise ToolchainError(
                    f"{' '.join(self.command)}\nfailed (exit {self._proc.returncode}):\n" + "\n".join(errors[:20])
                )
            self._tmp.replace(self.exe)
            self._proc = None
        return self.exe

    def run(self, urdf: Path, tip: str, locked: list[str], args: list[str], stdin: str | None = None) -> dict:
        """A fresh copy of the harness and of libpinocchio_default (where Pinocchio's algorithms
        are; found first through LD_LIBRARY_PATH) for each run: fresh_copy."""
        round_dir = Path(self._rounds.name)
        exe = fresh_copy(self.wait(), round_dir)
        env = dict(os.environ)
        if self.instantiation == "library":
            fresh_copy(self.tool["prefix"] / "lib" / "libpinocchio_default.so", round_dir)
            env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(round_dir), env.get("LD_LIBRARY_PATH")]))
        cmd = [str(exe), str(urdf), tip, *(["--lock", ",".join(locked)] if locked else []), *args]
        res = subprocess.run(cmd, input=stdin, capture_output=True, text=True, env=env)
        if res.returncode != 0:
            raise ToolchainError(f"{' '.join(cmd)} failed (exit {res.returncode}): {res.stderr.strip()}")
        return json.loads(res.stdout)

    def describe(self) -> dict:
        return {
            "compiler": self.compiler,
            "flags": self.flags,
            "command": " ".join(self.command),
            "template_instantiation": self.instantiation,
            "eigen": self.tool["eigen"],
            "urdf_headers": self.tool["urdf_headers"],
            "cached": self.cached,
        }


def rel_err(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def check_against_pinocchio(module, name: str, urdf: Path, tip: str, locked: list[str], harness) -> dict:
    """One random state: generated module vs Pinocchio (Python) vs the C++ harness, <= 1e-9."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    if locked:
        model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
    if model.nq != module.nq:
        sys.exit(f"bench: {name}: Pinocchio's model has nq = {model.nq}, robotgen's {module.nq}")
    data, fid = model.createData(), model.getFrameId(tip)
    damping = np.array([j["damping"] for j in module.info()["nodes"][name]["joints"]])
    rng = np.random.default_rng(2024)
    q, qd, x = rng.uniform(-np.pi, np.pi, model.nq), rng.uniform(-2, 2, model.nq), rng.uniform(-2, 2, model.nq)
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin_py = {
        "mass": M,
        "inverse_dynamics": pin.rnea(model, data, q, qd, x).copy(),
        "gravity": pin.computeGeneralizedGravity(model, data, q).copy(),
        "jacobian": pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED),
        "coriolis": pin.computeCoriolisMatrix(model, data, q, qd).copy(),
        "forward_dynamics": pin.aba(model, data, q, qd, x).copy(),
    }
    # robotgen's URDF <dynamics damping> is viscous friction in inverse/forward dynamics.
    generated = {
        "mass": module.mass(q),
        "gravity": module.gravity(q),
        "jacobian": module.jacobian(q),
        "coriolis": module.coriolis(q, qd),
        "inverse_dynamics": module.inverse_dynamics(q, qd, x) - damping * qd,
        "forward_dynamics": module.forward_dynamics(q, qd, x + damping * qd),
    }
    D = np.diag(damping)
    pin.computeRNEADerivatives(model, data, q, qd, x)
    pin_py["inverse_dynamics_derivatives"] = np.hstack([data.dtau_dq, data.dtau_dv + D])
    generated["inverse_dynamics_derivatives"] = np.hstack(module.inverse_dynamics_derivatives(q, qd, x))
    pin.computeABADerivatives(model, data, q, qd, x - damping * qd)
    Minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
    pin_py["forward_dynamics_derivatives"] = np.hstack([data.ddq_dq, data.ddq_dv - Minv @ D, Minv])
    generated["forward_dynamics_derivatives"] = np.hstack(module.forward_dynamics_derivatives(q, qd, x))
    cxx = harness.run(urdf, tip, locked, ["--eval"], " ".join(f"{v:.17g}" for v in (*q, *qd, *x)))
    errors = {}
    for fn in PIN_FUNCTIONS:
        errors[fn] = {"robotgen_vs_pinocchio": rel_err(generated[fn], pin_py[fn])}
        if fn in cxx:  # the C++ harness evaluates the functions it times, less the derivatives
            errors[fn]["pinocchio_cxx_vs_python"] = rel_err(np.reshape(cxx[fn], np.shape(pin_py[fn])), pin_py[fn])
    bad = {fn: e for fn, e in errors.items() if max(e.values()) > CHECK_TOL}
    if bad:
        sys.exit(
            f"bench: {name}: robotgen and Pinocchio disagree (relative error > {CHECK_TOL:g}), "
            f"not timing wrong code: {bad}"
        )
    return errors


def op_counts(out: Path) -> dict:
    manifest = json.loads((out / "manifest.json").read_text())
    return {
        f["name"]: {"arithmetic_ops": f.get("arithmetic_ops"), "sin_cos_ops": f.get("sin_cos_ops")}
        for f in manifest["functions"]
    }


def versus_table(robots: list[dict]) -> str:
    head = [
        "robot",
        "function",
        "robotgen C ns",
        "Pinocchio ns",
        "Pin/robotgen",
        "ops",
        "sin/cos",
        "floor ns",
        "efficiency",
    ]
    lines = [head]
    for r in robots:
        for f in r["functions"]:
            lines.append(
                [
                    r["robot"],
                    f["function"],
                    f"{f['robotgen_c']['ns_min']:.1f}",
                    f"{f['pinocchio']['ns_min']:.1f}",
                    f"{f['ratio']:.2f}",
                    str(f["arithmetic_ops"]),
                    str(f["sin_cos_ops"]),
                    f"{f['floor_ns']:.1f}",
                    f"{f['efficiency']:.2f}",
                ]
            )
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    fmt = lambda row: "  ".join(s.rjust(w) if i > 1 else s.ljust(w) for i, (s, w) in enumerate(zip(row, widths)))  # noqa: E731
    return "\n".join([fmt(lines[0]), fmt(["-" * w for w in widths])] + [fmt(r) for r in lines[1:]])


def build_urdf(name: str, out: Path):
    from robotgen.cli import main as robotgen_main

    rel, tip = URDF_ROBOTS[name]
    urdf = robots_dir() / rel
    status = robotgen_main(["build", str(urdf), "--tip", tip, "--name", name, "-o", str(out)])
    if status != 0:
        sys.exit(f"bench: robotgen build {urdf} --tip {tip} failed with exit status {status}")
    sys.path.insert(0, str(out))
    importlib.invalidate_caches()
    module = importlib.import_module(name)
    locked = list(module.info()["nodes"][name].get("locked_joints", []))
    return urdf, tip, module, locked


def time_versus(built: dict, harness: PinocchioHarness, tmp: Path, rounds: int, machine: dict) -> list[dict]:
    """Alternating rounds of the C harness and the Pinocchio harness per robot; min over rounds."""
    robots = []
    for name, b in built.items():
        best_c: dict = {}
        best_p: dict = {}
        c_info = None
        for _ in range(rounds):
            c_info = run_c(b["out"], name, b["nq"], PIN_FUNCTIONS, tmp / f"c-{name}")
            p = harness.run(b["urdf"], b["tip"], b["locked"], PIN_FUNCTIONS)
            for best, res in ((best_c, c_info["results"]), (best_p, p["results"])):
                for fn, t in res.items():
                    if fn not in best or t["ns_min"] < best[fn]["ns_min"]:
                        best[fn] = t
        ops = op_counts(b["out"])
        robots.append(
            {
                "robot": name,
                "urdf": b["urdf_rel"],
                "tip": b["tip"],
                "nq": b["nq"],
                "locked_joints": b["locked"],
                "check": b["check"],
                "c_command": c_info["command"],
                "functions": [
                    {
                        "function": fn,
                        "pinocchio_call": PIN_CALLS[fn],
                        "robotgen_c": best_c[fn],
                        "pinocchio": best_p[fn],
                        "ratio": best_p[fn]["ns_min"] / best_c[fn]["ns_min"],
                        **ops[fn],
                        "floor_ns": floor_ns(ops[fn]["arithmetic_ops"], ops[fn]["sin_cos_ops"], machine),
                        "efficiency": floor_ns(ops[fn]["arithmetic_ops"], ops[fn]["sin_cos_ops"], machine)
                        / best_c[fn]["ns_min"],
                    }
                    for fn in PIN_FUNCTIONS
                ],
            }
        )
    return robots


def fused_section(robots: list[tuple[str, Path, int]], tmp: Path, versus: list[dict], rounds: int) -> list[dict]:
    """servo_terms (M, C qd + N, J, Jdot qd in one call) against the four separate calls, and
    against Pinocchio's crba + rnea + computeFrameJacobian timed apart in the same run; each the
    least of ``rounds`` runs, as the kernels against Pinocchio are."""
    rows = []
    pinocchio = {r["robot"]: {f["function"]: f["pinocchio"]["ns_min"] for f in r["functions"]} for r in versus}
    print(
        "\nbench: fused servo terms (one call) vs mass + nonlinear + jacobian + jacobian_dot_qd, and vs "
        "Pinocchio's crba + rnea + computeFrameJacobian"
    )
    for name, out, nq in robots:
        runs = [
            run_c(out, name, nq, ["servo_terms", "servo_terms_separate"], tmp / f"fused-{name}")["results"]
            for _ in range(rounds)
        ]
        fused, separate = (min(r[f]["ns_min"] for r in runs) for f in ("servo_terms", "servo_terms_separate"))
        row = {"robot": name, "fused_ns": fused, "separate_ns": separate, "speedup": separate / fused}
        line = f"  {name:10s} fused {fused:8.1f} ns   separate {separate:8.1f} ns   speedup {separate / fused:4.2f}x"
        if name in pinocchio:
            p = pinocchio[name]
            row["pinocchio_separate_ns"] = p["mass"] + p["inverse_dynamics"] + p["jacobian"]
            row["versus_pinocchio"] = row["pinocchio_separate_ns"] / fused
            line += (
                f"   Pinocchio crba + rnea + J {row['pinocchio_separate_ns']:8.1f} ns: {row['versus_pinocchio']:5.2f}x"
            )
        rows.append(row)
        print(line)
    return rows


def native_section(built: dict, tmp: Path, rounds: int) -> list[dict]:
    """The same generated C compiled for this CPU (-march=native; -ffp-contract=off keeps
    a * b + c unfused, so it computes the same bits) against the portable build, alternating
    rounds."""
    native = [*CFLAGS, "-march=native", "-ffp-contract=off"]  # as the extension's build adds
    functions = [*PIN_FUNCTIONS, "servo_terms"]
    print(
        f"\nbench: the same C built for this CPU ({' '.join(native)}) vs the portable build "
        f"({' '.join(CFLAGS)}), least of {rounds} alternating rounds"
    )
    rows = []
    for name, b in built.items():
        best: dict = {}
        for _ in range(rounds):
            for label, flags in (("portable", CFLAGS), ("native", native)):
                res = run_c(b["out"], name, b["nq"], functions, tmp / f"{label}-{name}", flags=flags)["results"]
                for fn, t in res.items():
                    best.setdefault(fn, {})[label] = min(t["ns_min"], best.get(fn, {}).get(label, math.inf))
        for fn in functions:
            t = best[fn]
            rows.append(
                {
                    "robot": name,
                    "function": fn,
                    "portable_ns": t["portable"],
                    "native_ns": t["native"],
                    "speedup": t["portable"] / t["native"],
                }
            )
    header = f"{'robot':6s} {'function':30s} {'portable ns':>11s} {'native ns':>10s} {'speedup':>8s}"
    print(header + "\n" + "-" * len(header))
    for r in rows:
        print(
            f"{r['robot']:6s} {r['function']:30s} {r['portable_ns']:11.1f} {r['native_ns']:10.1f} {r['speedup']:8.2f}"
        )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", help="spec to benchmark (default specs/puma560.yaml)")
    ap.add_argument("--out", help="build directory (default: a temporary directory)")
    ap.add_argument("--json", default=str(HERE / "results.json"), help="where to write the results")
    ap.add_argument("--functions", nargs="*", default=FUNCTIONS)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    ap.add_argument(
        "--urdf",
        nargs="*",
        choices=sorted(URDF_ROBOTS),
        help="URDF arms to compare with Pinocchio's C++ (default: ur5 panda, none with --spec)",
    )
    ap.add_argument(
        "--pinocchio-headers",
        action="store_true",
        help="instantiate Pinocchio's algorithms from its headers at -O2 in the harness "
        "(a ~2.5 min compile) instead of calling the wheel's libpinocchio_default",
    )
    args = ap.parse_args(argv)

    spec = Path(args.spec or ROOT / "specs" / "puma560.yaml").resolve()
    urdf_names = args.urdf if args.urdf is not None else ([] if args.spec else list(URDF_ROBOTS))
    tmp = tempfile.mkdtemp(prefix="robotgen-bench-")
    status = 0
    try:
        # The Pinocchio harness compiles in the background while robotgen builds (not while timing).
        harness, versus = None, None
        if urdf_names:
            try:
                harness = PinocchioHarness(args.pinocchio_headers)
            except ToolchainError as e:
                versus = {"error": str(e)}

        out = Path(args.out).resolve() if args.out else Path(tmp) / "build"
        name = build(spec, out)
        sys.path.insert(0, str(out))
        module = importlib.import_module(name)
        nq = int(module.nq)

        built = {}
        for rname in urdf_names:
            rout = Path(tmp) / f"build-{rname}"
            urdf, tip, rmodule, locked = build_urdf(rname, rout)
            built[rname] = {
                "out": rout,
                "urdf": urdf,
                "tip": tip,
                "module": rmodule,
                "locked": locked,
                "nq": int(rmodule.nq),
                "urdf_rel": str(urdf.relative_to(robots_dir().parent.parent)),
            }
        if harness is not None:
            try:
                harness.wait()
                for rname, b in built.items():
                    b["check"] = check_against_pinocchio(b["module"], rname, b["urdf"], b["tip"], b["locked"], harness)
                    worst = max(max(e.values()) for e in b["check"].values())
                    print(
                        f"bench: {rname}: generated module, Pinocchio (Python) and the C++ harness agree, "
                        f"max relative error {worst:.1e} <= {CHECK_TOL:g}",
                        flush=True,
                    )
            except ToolchainError as e:
                versus, harness = {"error": str(e)}, None

        from robotgen.frontend import load_system
        from robotgen.symbolic import kernels_for

        kernels = {k.name: k for k in kernels_for(load_system(str(spec)))}
        functions = [f for f in args.functions if f in kernels and hasattr(module, f)]

        print(f"bench: {name} (nq = {nq}), C: {' '.join(CFLAGS)}", flush=True)
        c = run_c(out, name, nq, functions, Path(tmp), single_calls=True)
        rows = []
        for fn in functions:
            rows.append(
                {
                    "function": fn,
                    "c": c["results"][fn],
                    "python": run_python(module, fn, nq, args.quick),
                    "casadi": run_casadi(kernels[fn], nq, args.quick),
                }
            )
        single_call_rounds(rows, module, out, name, nq, Path(tmp), 1 if args.quick else 3, args.quick)
        print(table(rows))
        print(
            "C ns: calls back to back (the core overlaps consecutive calls); C 1 call: one call at a time "
            "(lfence between calls), as a Python call makes it; Py out=: the result written into a given "
            "array; Py-C 1 call: what the Python call f(q, ...) costs over the C call (C 1 call and Py: the "
            "least of alternating rounds)"
        )

        if harness is not None:
            import pinocchio as pin

            print(
                f"\nbench: generated C ({' '.join(CFLAGS)}) vs Pinocchio {pin.__version__} C++ "
                f"({' '.join(harness.flags)}; algorithms from the wheel's "
                f"{'libpinocchio_default.so' if harness.instantiation == 'library' else 'headers, compiled here'})",
                flush=True,
            )
            machine = calibrate(out, name, nq, Path(tmp) / "calibrate")
            print(
                f"bench: this machine, measured: scalar peak {machine['peak_ops_per_ns']:.2f} operations/ns, "
                f"libm sin+cos {machine['sincos_ns']:.2f} ns; a kernel's floor is its operations at that peak "
                "plus its sin/cos pairs at that cost",
                flush=True,
            )
            robots = time_versus(built, harness, Path(tmp), 1 if args.quick else 2, machine)
            print(versus_table(robots))
            print(
                "ratio = Pinocchio ns / robotgen ns (> 1: the generated C is faster); ops: arithmetic "
                "operations in the generated kernel (manifest.json)"
            )
            versus = {
                "pinocchio": pin.__version__,
                "c_flags": CFLAGS,
                "pinocchio_harness": harness.describe(),
                "rounds": 1 if args.quick else 2,
                "check_tolerance": CHECK_TOL,
                "units": "ns per call, min over repeats and rounds; ratio = pinocchio / robotgen_c",
                "notes": [
                    "both harnesses cycle through the same 256 random states (the same LCG)",
                    "robotgen's inverse_dynamics and forward_dynamics include the URDF joint damping "
                    "as viscous friction (Panda: 0.003); Pinocchio's rnea and aba do not",
                    "Pinocchio's crba fills the upper triangle of M; robotgen's mass returns the full matrix",
                ],
                "robots": robots,
                "machine_floor": machine,
            }
        elif versus is not None:
            print(f"\nbench: Pinocchio C++ comparison not run: {versus['error']}", file=sys.stderr)
            status = 1

        result = {
            "robot": name,
            "spec": os.path.relpath(spec, ROOT),
            "nq": nq,
            "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "machine": {
                "platform": platform.platform(),
                "processor": platform.processor() or platform.machine(),
                "cpus": os.cpu_count(),
                "python": platform.python_version(),
            },
            "casadi": __import__("casadi").__version__,
            "numpy": np.__version__,
            "c": {k: v for k, v in c.items() if k != "results"},
            "batch_size": BATCH,
            "quick": args.quick,
            "units": "ns per call (min over repeats); *_batch / *_map: ns per state",
            "functions": rows,
        }
        if versus is not None:
            result["versus_pinocchio"] = versus
        result["fused_servo_terms"] = fused_section(
            [(name, out, nq)] + [(n, b["out"], b["nq"]) for n, b in (built or {}).items()],
            Path(tmp),
            versus.get("robots", []) if versus else [],
            1 if args.quick else 2,
        )
        if built and not args.quick:
            result["native_build"] = native_section(built, Path(tmp), 2)
        path = Path(args.json)  # bench/code_generators.py's section of it is its own: kept
        previous = json.loads(path.read_text()) if path.exists() else {}
        if "code_generators" in previous:
            result["code_generators"] = previous["code_generators"]
        path.write_text(json.dumps(result, indent=2) + "\n")
        print(f"bench: wrote {args.json}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
