"""Pinocchio's code generation (CppADCodeGen) as a peer: the generator program
(pinocchio_codegen.cpp, compiled once against the pin wheel's headers and cached in bench/out/),
its C for one arm (cached by the model), and the functions the harness calls.

The packages: the pin wheel (Pinocchio's headers and its URDF parser), cmeel-cppad and
cmeel-cppadcodegen (CppAD and CppADCodeGen, headers), cmeel-eigen and cmeel-urdfdom-headers.
`make bench` installs them; without them this peer says why and the bench goes on.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
CACHE = HERE.parent / "out" / "peers"
GENERATOR_FLAGS = ["-std=c++17", "-O1", "-DNDEBUG", "-Wno-deprecated-declarations"]  # the generator only traces


class PeerUnavailable(Exception):
    """A peer cannot be built here; the message says why."""


@dataclass(frozen=True)
class PeerFunction:
    """One generated function the harness calls: robotgen's KERNEL computed by WHO's VARIANT,
    from SOURCE, in the convention CONVENTION ("cppadcg": f(in, out, atomics) with in[0] the
    packed state; "casadi": f(arg, res, iw, w, mem)), its outputs laid out as LAYOUT (a key of
    harness.reference's values)."""

    kernel: str
    who: str
    variant: str
    symbol: str
    source: Path
    convention: str
    layout: str
    outputs: int
    inputs: int = 3  # 1: q only
    out_sizes: tuple[int, ...] = ()
    work: tuple[int, int, int, int] = (0, 0, 0, 0)  # CasADi's sz_arg, sz_res, sz_iw, sz_w


# (kernel, variant, CppADCodeGen's function: forward_zero or jacobian, layout): every variant
# pinocchio_codegen.cpp writes; the best of a kernel's variants is the reference.
VARIANTS = [
    ("mass", "crba", "forward_zero", "mass_upper"),
    ("inverse_dynamics", "rnea", "forward_zero", "tau"),
    ("forward_dynamics", "aba", "forward_zero", "ddq"),
    ("forward_dynamics", "crba_cholesky_fd", "forward_zero", "ddq"),
    ("mass_inverse", "minv", "forward_zero", "mass_inverse_upper"),
    ("mass_inverse", "crba_cholesky_minv", "forward_zero", "mass_inverse_upper"),
    ("inverse_dynamics_derivatives", "rnea_derivatives", "forward_zero", "dtau_dq_dv_da"),
    ("inverse_dynamics_derivatives", "rnea_derivatives_dq_dv", "forward_zero", "dtau_dq_dv"),
    ("inverse_dynamics_derivatives", "rnea", "jacobian", "rnea_jacobian"),
    ("forward_dynamics_derivatives", "aba_derivatives", "forward_zero", "dddq"),
    ("forward_dynamics_derivatives", "crba_cholesky_fd_derivatives", "forward_zero", "dddq"),
    ("forward_dynamics_derivatives", "aba", "jacobian", "aba_jacobian"),
]


def _versions() -> dict:
    out = {}
    for dist in ("pin", "cmeel-cppad", "cmeel-cppadcodegen", "cmeel-eigen"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


class Generator:
    """pinocchio_codegen.cpp compiled (in the background; cached in bench/out/peers/)."""

    def __init__(self, toolchain: dict):
        self.versions = _versions()
        include = Path(toolchain["prefix"]) / "include"
        if not (include / "cppad" / "cg.hpp").is_file() or not (include / "cppad" / "cppad.hpp").is_file():
            raise PeerUnavailable(
                f"CppAD / CppADCodeGen headers not found in {include} "
                "(pip install cmeel-cppad cmeel-cppadcodegen==2.4.3)"
            )
        cxx = os.environ.get("CXX", "g++")
        try:
            version = subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
        except (OSError, IndexError) as e:
            raise PeerUnavailable(f"C++ compiler {cxx!r} cannot be run: {e}") from None
        src = HERE / "pinocchio_codegen.cpp"
        tail = [*toolchain["defines"], *toolchain["includes"], str(src), *toolchain["libs"]]
        self.key = hashlib.sha256(
            "\0".join([src.read_text(), version, repr(sorted(self.versions.items())), *GENERATOR_FLAGS, *tail]).encode()
        ).hexdigest()[:16]
        CACHE.mkdir(parents=True, exist_ok=True)
        self.exe = CACHE / f"pinocchio_codegen-{self.key}"
        self.command = [cxx, *GENERATOR_FLAGS, *tail, "-o", str(self.exe)]
        self.cached = self.exe.exists()
        self._proc = None
        if not self.cached:
            self._tmp = self.exe.with_name(self.exe.name + ".tmp")
            self._proc = subprocess.Popen(
                [*self.command[:-1], str(self._tmp)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
            )

    def wait(self) -> Path:
        if self._proc is not None:
            log, _ = self._proc.communicate()
            self._proc, failed = None, self._proc.returncode
            if failed:
                errors = [ln for ln in log.splitlines() if "error" in ln] or log.splitlines()[-20:]
                raise PeerUnavailable(f"{' '.join(self.command)}\nfailed (exit {failed}):\n" + "\n".join(errors[:20]))
            self._tmp.replace(self.exe)
        return self.exe

    def describe(self) -> dict:
        return {"generator": " ".join(self.command), "cached": self.cached, "versions": self.versions}

    def functions(self, arm_name: str, model_urdf: Path, nq: int) -> list[PeerFunction]:
        """Every variant's C for the model in MODEL_URDF, generated once per model (cached)."""
        exe = self.wait()
        key = hashlib.sha256(f"{self.key}\0{model_urdf.read_text()}".encode()).hexdigest()[:16]
        out = CACHE / "pinocchio-cg" / f"{arm_name}-{key}"
        if not (out / "done").exists():
            out.mkdir(parents=True, exist_ok=True)
            res = subprocess.run([str(exe), str(model_urdf), str(out)], capture_output=True, text=True)
            if res.returncode != 0:
                raise PeerUnavailable(
                    f"{exe.name} {model_urdf} failed (exit {res.returncode}): {res.stderr.strip()[-2000:]}"
                )
            (out / "done").write_text(res.stdout)
        return [function(kernel, variant, kind, layout, out, nq) for kernel, variant, kind, layout in VARIANTS]


def function(kernel: str, variant: str, kind: str, layout: str, out: Path, n: int) -> PeerFunction:
    symbol = f"pcg_{variant}_{kind}"
    outputs = {
        "mass_upper": n * (n + 1) // 2,
        "mass_inverse_upper": n * (n + 1) // 2,
        "tau": n,
        "ddq": n,
        "dtau_dq_dv_da": 3 * n * n,
        "dtau_dq_dv": 2 * n * n,
        "dddq": 3 * n * n,
        "rnea_jacobian": 3 * n * n,
        "aba_jacobian": 3 * n * n,
    }[layout]
    return PeerFunction(
        kernel,
        "pinocchio_cg",
        variant if kind == "forward_zero" else f"{variant}_ad_jacobian",
        symbol,
        out / variant / f"{symbol}.c",
        "cppadcg",
        layout,
        outputs,
        inputs=1 if kernel in ("mass", "mass_inverse") else 3,
    )
