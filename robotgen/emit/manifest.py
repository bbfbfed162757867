"""manifest.json: what was built, from what, and how big each function is."""
from __future__ import annotations

from robotgen.emit.context import ModuleView, PortView, to_json


def manifest_json(view: ModuleView) -> str:
    """Deterministic text (sorted keys, no timestamps or paths): the module's info()
    plus the CasADi version and each function's ports and operation counts."""
    manifest = {
        **view.info,
        "casadi_version": view.casadi_version,
        "functions": [
            {
                "name": f.name,
                "c_name": f.c_name,
                "doc": f.doc,
                "inputs": [_port(p) for p in f.inputs],
                "outputs": [_port(p) for p in f.outputs],
                "arithmetic_ops": f.arithmetic_ops,
                "sin_cos_ops": f.sin_cos_ops,
            }
            for f in view.functions
        ],
    }
    return to_json(manifest) + "\n"


def _port(port: PortView) -> dict:
    return {"name": port.name, "shape": list(port.shape)}
