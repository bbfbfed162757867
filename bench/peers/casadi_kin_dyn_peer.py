"""casadi_kin_dyn as a peer: Pinocchio's algorithms traced into CasADi SX graphs, then CasADi's
C. Its PyPI wheel (cmeel-casadi-kin-dyn) pins an older Pinocchio (2.6) and CasADi (3.6) than
robotgen's, so `make bench` installs it into a virtual environment of its own,
bench/out/casadi-kin-dyn/ (or the Python named by $CASADI_KIN_DYN_PYTHON), and
casadi_kin_dyn_codegen.py runs there; what comes back is C and a listing of its functions.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
from pathlib import Path

from .pinocchio_cg import CACHE, PeerFunction, PeerUnavailable

HERE = Path(__file__).resolve().parent
VENV = HERE.parent / "out" / "casadi-kin-dyn"
# what each generated function's outputs hold (harness.reference's keys): matrices row-major and whole
LAYOUTS = {
    "crba": "mass",
    "rnea": "tau",
    "aba": "ddq",
    "crba_ldl": "ddq",
    "rnea_jacobian": "dtau_dq_dv",
    "aba_jacobian": "dddq",
    "crba_ldl_jacobian": "dddq",
}
MASS_INVERSE_LAYOUT = "mass_inverse"


def python() -> Path:
    path = Path(os.environ.get("CASADI_KIN_DYN_PYTHON", VENV / "bin" / "python"))
    if not path.exists():
        raise PeerUnavailable(
            f"no casadi_kin_dyn environment at {path} (`make bench` makes it: python -m venv "
            f"{VENV} && {VENV}/bin/python -m pip install cmeel-casadi-kin-dyn==1.6.14)"
        )
    return path


def environment(py: Path) -> dict:
    """Its cmeel libraries (libcasadi) where the loader finds them."""
    env = dict(os.environ)
    libs = sorted(py.parent.parent.glob("lib/python*/site-packages/cmeel.prefix/lib"))
    env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [*map(str, libs), env.get("LD_LIBRARY_PATH")]))
    return env


def version() -> str:
    py = python()
    ask = "from importlib.metadata import version; print(version('cmeel-casadi-kin-dyn'))"
    res = subprocess.run([str(py), "-I", "-c", ask], capture_output=True, text=True, env=environment(py))
    if res.returncode != 0:
        raise PeerUnavailable(f"casadi_kin_dyn is not installed in {py}: {res.stderr.strip()[-500:]}")
    return res.stdout.strip()


def functions(arm_name: str, model_urdf: Path) -> tuple[list[PeerFunction], dict]:
    """casadi_kin_dyn's functions for the model in MODEL_URDF as C (cached by the model) and
    what built them."""
    py = python()
    release = version()
    script = HERE / "casadi_kin_dyn_codegen.py"
    key = hashlib.sha256("\0".join([script.read_text(), release, model_urdf.read_text()]).encode()).hexdigest()[:16]
    out = CACHE / "casadi-kin-dyn" / f"{arm_name}-{key}"
    c_file, listing = out / "casadi_kin_dyn_peer.c", out / "functions.json"
    if not listing.exists():
        out.mkdir(parents=True, exist_ok=True)
        res = subprocess.run(
            [str(py), "-I", str(script), str(model_urdf), str(c_file), str(listing) + ".tmp"],
            capture_output=True,
            text=True,
            env=environment(py),
        )
        if res.returncode != 0:
            raise PeerUnavailable(
                f"{script.name} {model_urdf} failed (exit {res.returncode}): {res.stderr.strip()[-2000:]}"
            )
        Path(str(listing) + ".tmp").replace(listing)
    made = json.loads(listing.read_text())
    found = []
    for f in made["functions"]:
        layout = MASS_INVERSE_LAYOUT if f["kernel"] == "mass_inverse" else LAYOUTS[f["variant"]]
        found.append(
            PeerFunction(
                f["kernel"],
                "casadi_kin_dyn",
                f["variant"],
                f["function"],
                c_file,
                "casadi",
                layout,
                sum(f["out_sizes"]),
                inputs=f["n_in"],
                out_sizes=tuple(f["out_sizes"]),
                work=(f["sz_arg"], f["sz_res"], f["sz_iw"], f["sz_w"]),
            )
        )
    return found, {"casadi_kin_dyn": release, "casadi": made["casadi"], "python": str(py)}
