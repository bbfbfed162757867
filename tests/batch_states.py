"""What the batch tests share: a module built from chosen kernels, random states (angles past
rg_sincos2's bound among them) and each state's single call."""

from __future__ import annotations

import importlib.util

import numpy as np

from robotgen.emit import compile as emit_compile
from robotgen.emit.build import emit


def load(out, name):
    spec = importlib.util.spec_from_file_location(name, out / name / f"{name}{emit_compile.extension_suffix()}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def built(tmp_path_factory, name, kernels, nq, wanted, precision="double"):
    out = tmp_path_factory.mktemp(name)
    chosen = [k for k in kernels if k.name in wanted]
    assert {k.name for k in chosen} == set(wanted)
    emit(out / name, name, chosen, nq=nq, precision=precision)
    return load(out, name), chosen


def states(kernel, n: int, rng) -> list[np.ndarray]:
    """n random states; every 7th state's angles past 1e5 (rg_sincos2 leaves them to libm), and
    every 5th (from the 3rd) one angle past it, each coordinate in turn: its pair goes to libm,
    the kernel's other angles do not."""
    arrays = []
    for port in kernel.inputs:
        if port.name == "dt":
            arrays.append(rng.uniform(1e-3, 1e-2, (n, 1)))
            continue
        a = rng.uniform(-3.0, 3.0, (n, port.size))
        if port.name == "q":
            a[::7] += 3e5
            for k in range(3, n, 5):
                a[k, (k // 5) % port.size] += 3e5
        arrays.append(a)
    return arrays


def single_calls(fn, arrays, n, outputs):
    """Each state's single call: its results, or the results it leaves in arrays holding -7
    (untouched on status 1, zeros on status 2), and whether it raised."""
    results = [np.full((n, p.size), -7.0) for p in outputs]
    failed = []
    for k in range(n):
        out = tuple(r[k].reshape(p.rows, p.cols) if p.cols > 1 else r[k] for r, p in zip(results, outputs))
        try:
            fn(*(a[k] for a in arrays), out=out if len(out) > 1 else out[0])
        except FloatingPointError:
            failed.append(k)
    return results, failed
