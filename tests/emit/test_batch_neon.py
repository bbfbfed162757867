"""The NEON lanes (robotgen.emit.lanes), run: the emitted C cross-compiled for aarch64 with
robotgen's flags and run under qemu's user-mode emulator. Every batch call, at each width the
source compiles there (2 doubles or 4 floats a vector), must give the single calls' bits, and
the single calls on aarch64 must give the x86 module's bits for the same states (rg_sincos2
and uncontracted arithmetic: the same IEEE operations on both). Skipped where the cross
compiler (gcc-aarch64-linux-gnu) or qemu-aarch64 (qemu-user) is not installed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from batch_states import built, single_calls, states
from robots import PANDA, UR5, robots_dir

from robotgen.emit import lanes
from robotgen.frontend.urdf import load_urdf_system
from robotgen.model.describe import system_nq
from robotgen.symbolic import kernels_for

CROSS, QEMU = "aarch64-linux-gnu-gcc", "qemu-aarch64"
CAPS = (2, 4, 8, 16)
N = 1023  # not a multiple of any width: the leftover states go through the single function

pytestmark = pytest.mark.skipif(
    shutil.which(CROSS) is None or shutil.which(QEMU) is None,
    reason=f"needs {CROSS} and {QEMU} (apt-get install gcc-aarch64-linux-gnu qemu-user)",
)


def checker(name: str, real: str, functions: list[dict]) -> str:
    """C that reads each function's N input states from argv[1], calls it N times and its batch
    at every cap, fails on the first batch that differs from the single calls, writes the single
    calls' results to argv[2] and prints the widths taken."""
    lines = [
        "#include <stdio.h>",
        "#include <stdlib.h>",
        "#include <string.h>",
        f'#include "{name}.h"',
        f"static {real} *take(FILE *f, size_t count) {{",
        f"  {real} *a = malloc(count * sizeof *a);",
        "  if (!a || fread(a, sizeof *a, count, f) != count) exit(2);",
        "  return a;",
        "}",
        f"static void sentinel({real} *a, size_t count) {{ size_t i; for (i = 0; i < count; ++i) a[i] = -7; }}",
        "int main(int argc, char **argv) {",
        f"  int caps[{len(CAPS)}] = {{{', '.join(map(str, CAPS))}}}, c, k;",
        '  FILE *in = argc > 2 ? fopen(argv[1], "rb") : NULL, *out = argc > 2 ? fopen(argv[2], "wb") : NULL;',
        "  if (!in || !out) return 2;",
        '  printf("[");',
        f'  for (c = 0; c < {len(CAPS)}; ++c) printf("%s%d", c ? ", " : "", {name}_batch_lanes(caps[c]));',
        '  printf("]\\n");',
    ]
    for f in functions:
        size = {p["name"]: int(np.prod(p["shape"])) for p in f["inputs"] + f["outputs"]}
        ins, outs = [p["name"] for p in f["inputs"]], [p["name"] for p in f["outputs"]]
        single = ", ".join(
            [f"{a} + (size_t)k * {size[a]}" for a in ins] + [f"{o}_1 + (size_t)k * {size[o]}" for o in outs]
        )
        lines.append("  {")
        lines += [f"    {real} *{a} = take(in, {N} * {size[a]});" for a in ins]
        for o in outs:
            lines += [
                f"    {real} *{o} = malloc({N} * {size[o]} * sizeof *{o}), *{o}_1 = malloc({N} * {size[o]} * sizeof *{o});",
                f"    sentinel({o}_1, {N} * {size[o]});",
            ]
        lines.append(f"    for (k = 0; k < {N}; ++k) (void){f['c_name']}({single});")
        lines.append(f"    for (c = 0; c < {len(CAPS)}; ++c) {{")
        lines += [f"      sentinel({o}, {N} * {size[o]});" for o in outs]
        lines.append(f"      (void){f['c_name']}_batch_lanes(caps[c], {N}, {', '.join(ins + outs)});")
        for o in outs:
            lines.append(
                f"      if (memcmp({o}, {o}_1, {N} * {size[o]} * sizeof *{o})) {{"
                f' fprintf(stderr, "{f["name"]}.{o}: %d lanes differ from single calls\\n", {name}_batch_lanes(caps[c]));'
                " return 1; }"
            )
        lines.append("    }")
        lines += [f"    fwrite({o}_1, sizeof *{o}_1, {N} * {size[o]}, out);" for o in outs]
        lines.append("  }")
    lines += ["  return fclose(out) != 0;", "}"]
    return "\n".join(lines) + "\n"


def run_on_aarch64(module, kernels, tmp_path, rng):
    """The checker's widths, and per kernel (states, the aarch64 single calls' results)."""
    out = os.path.dirname(module.__file__)
    name = module.__name__
    manifest = json.loads(open(os.path.join(out, "manifest.json")).read())
    functions = [f for f in manifest["functions"] if f["name"] in lanes.BATCH_FUNCTIONS]
    real = manifest["precision"]
    dtype = np.float64 if real == "double" else np.float32
    by_name = {k.name: k for k in kernels}
    inputs = {f["name"]: states(by_name[f["name"]], N, rng) for f in functions}
    with open(tmp_path / "in.bin", "wb") as f:
        for fn in functions:
            for a in inputs[fn["name"]]:
                f.write(a.astype(dtype).tobytes())
    (tmp_path / "check.c").write_text(checker(name, real, functions))
    exe = tmp_path / "check"
    flags = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-static"]
    build = subprocess.run(
        [CROSS, *flags, "-I", out, str(tmp_path / "check.c"), os.path.join(out, f"{name}.c"), "-lm", "-o", str(exe)],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    ran = subprocess.run(
        [QEMU, str(exe), str(tmp_path / "in.bin"), str(tmp_path / "out.bin")], capture_output=True, text=True
    )
    assert ran.returncode == 0, ran.stderr
    results = np.fromfile(tmp_path / "out.bin", dtype=dtype)
    got, at = {}, 0
    for fn in functions:
        kernel = by_name[fn["name"]]
        parts = []
        for p in kernel.outputs:
            parts.append(results[at : at + N * p.size].reshape(N, p.size))
            at += N * p.size
        got[fn["name"]] = parts
    assert at == results.size
    return json.loads(ran.stdout), inputs, got


def assert_as_on_x86(module, kernels, inputs, got):
    """The aarch64 single calls' bits are the x86 module's, state for state (but the states whose
    angles pass rg_sincos2's bound: those go to each machine's libm)."""
    for kernel in kernels:
        if kernel.name not in got:
            continue
        arrays = [a.astype(np.float64) for a in inputs[kernel.name]]
        expected, failed = single_calls(getattr(module, kernel.name), [a.copy() for a in arrays], N, kernel.outputs)
        assert not failed
        q = arrays[[p.name for p in kernel.inputs].index("q")]
        near = np.all(np.abs(q) < 1e5, axis=1)
        assert 0.6 * N < near.sum() < N
        for e, g, p in zip(expected, got[kernel.name], kernel.outputs):
            e = e.astype(g.dtype)
            same = np.all(e.view(np.uint8).reshape(N, -1) == g.view(np.uint8).reshape(N, -1), axis=1)
            assert same[near].all(), (
                f"{kernel.name}.{p.name}: states {np.flatnonzero(near & ~same)[:8]} differ from x86"
            )


@pytest.fixture(scope="module")
def ur5_system():
    return load_urdf_system(str(robots_dir() / UR5[0]), UR5[1])


@pytest.mark.parametrize("precision, width", [("double", 2), ("float", 4)])
def test_ur5_neon_batches_are_single_calls_and_x86s_bits(ur5_system, tmp_path_factory, tmp_path, precision, width):
    kernels = kernels_for(ur5_system)
    wanted = [k.name for k in kernels if k.name in lanes.BATCH_FUNCTIONS]
    assert len(wanted) >= 8
    module, chosen = built(
        tmp_path_factory, f"neon_ur5_{precision}", kernels, system_nq(ur5_system), wanted, precision=precision
    )
    taken, inputs, got = run_on_aarch64(module, chosen, tmp_path, np.random.default_rng(11))
    assert taken == [width if cap >= width else 1 for cap in CAPS]  # a cap below the vector: single calls
    assert_as_on_x86(module, chosen, inputs, got)


def test_panda_looped_derivatives_on_neon(tmp_path_factory, tmp_path):
    """The Panda's forward dynamics derivatives are loops (a schedule): their lane copy too."""
    system = load_urdf_system(str(robots_dir() / PANDA[0]), PANDA[1])
    kernels = kernels_for(system)
    module, chosen = built(
        tmp_path_factory, "neon_panda", kernels, system_nq(system), ("mass", "forward_dynamics_derivatives")
    )
    assert next(k for k in chosen if k.name == "forward_dynamics_derivatives").schedule is not None
    taken, inputs, got = run_on_aarch64(module, chosen, tmp_path, np.random.default_rng(12))
    assert taken == [2] * len(CAPS)
    assert_as_on_x86(module, chosen, inputs, got)
