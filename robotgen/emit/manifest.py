"""manifest.json: what was built, from what, and how big each function is."""

from __future__ import annotations

import hashlib

from robotgen.emit.context import ModuleView, to_json
from robotgen.emit.views import PortView


def manifest_json(view: ModuleView, sources: dict[str, str], targets: dict[str, dict] | None = None) -> str:
    """Deterministic text (sorted keys, no timestamps or paths): the module's info()
    (with its "parameters" list, name, shape, default and doc, when it has run-time
    parameters) plus the CasADi version, each function's ports (the parameter struct is not
    a port: "reads_parameters" says which functions take it) and operation counts, and the
    sha256 of every other emitted file (so a manifest alone pins a build byte for byte).
    ``targets``: what robotgen.emit.targets measured, only when the build asked for it."""
    manifest = {
        **view.info,
        "casadi_version": view.casadi_version,
        "files": {file: hashlib.sha256(text.encode("utf-8")).hexdigest() for file, text in sorted(sources.items())},
        "functions": [
            {
                "name": f.name,
                "c_name": f.c_name,
                "doc": f.doc,
                "inputs": [_port(p) for p in f.inputs],
                "outputs": [_port(p) for p in f.outputs],
                "arithmetic_ops": f.arithmetic_ops,
                "sin_cos_ops": f.sin_cos_ops,
                # only in a module with run-time parameters (info()["parameters"] lists them)
                **({"reads_parameters": f.reads_parameters} if view.parameters else {}),
            }
            for f in view.functions
        ],
        **({"targets": targets} if targets else {}),
    }
    return to_json(manifest) + "\n"


def _port(port: PortView) -> dict:
    return {"name": port.name, "shape": list(port.shape)}
