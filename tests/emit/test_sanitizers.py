"""The emitted C of every example under AddressSanitizer and UndefinedBehaviorSanitizer: every
function called on random inputs with huge values, zeros, NaN and Inf among them, and on the
spec's parameter defaults; every batch entry point (robotgen.emit.lanes) on BATCH states, one
round in ten, each port in a heap block of exactly its states (a block's loads may read past a
state's elements into the next states', never past the last). No finding is allowed (the
sanitizers abort the program on the first one); a NaN or Inf result is not a finding (the inputs
ask for it)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from robotgen.cli import main
from robotgen.emit.lanes import BATCH_FUNCTIONS

SPECS = Path(__file__).resolve().parents[2] / "specs"
CALLS = 3000  # rounds; each calls every function once
BATCH = 9  # states of a batch call: a block of 8 lanes and one left over, two of 4 and one
# the specs whose lanes are compiled here; the others' batch entry points loop over the single
# functions (-DRG_NO_LANES), since instrumented lane copies take three times as long to compile
# (the PUMA 560's 41 s of gcc's CPU against 15); its lanes (every transpose width) are a slow test
LANES = ("two_link",)
COMPILERS = [c for c in ("gcc", "clang") if shutil.which(c)]
SANITIZE = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g", "-O1"]


def harness(manifest: dict) -> str:
    """C that calls every function of the module with inputs from an LCG, one in eight of them
    a special value."""
    name = manifest["name"]
    size = max([1] + [max(1, _size(p)) for f in manifest["functions"] for p in f["inputs"] + f["outputs"]])
    batched = [f for f in manifest["functions"] if f["name"] in BATCH_FUNCTIONS]
    lines = [
        f'#include "{name}.h"',
        "#include <math.h>",
        "#include <stdio.h>",
        "#include <stdlib.h>",
        f"static double in[16][{size}], out[16][{size}];",
        "static unsigned long long s = 88172645463325252ULL;",
        "static double next(void) {",
        "    static const double special[8] = {0.0, -0.0, 1e300, -1e300, 1e-310, 0.0, 0.0, 0.0};",
        "    unsigned r;",
        "    s = s * 6364136223846793005ULL + 1442695040888963407ULL;",
        "    r = (unsigned)(s >> 40);",
        "    if ((r & 7) == 0) { int k = (int)((r >> 3) & 7); return k == 5 ? NAN : k == 6 ? INFINITY : "
        "k == 7 ? -INFINITY : special[k]; }",
        "    return ((double)(s >> 11) / 9007199254740992.0 - 0.5) * 8.0;",
        "}",
        # a batch port's own heap block, exactly its n states: a read or write past them is a finding
        "static double *fresh(size_t count) {",
        "    double *a = malloc(count * sizeof *a);",
        "    size_t i;",
        "    if (!a) abort();",
        "    for (i = 0; i < count; ++i) a[i] = next();",
        "    return a;",
        "}",
        "int main(void) {",
    ]
    if manifest.get("parameters"):
        lines.append(f"    const {name}_params params = {name.upper()}_PARAMS_DEFAULT;")
    lines += [
        "    int round, i, status = 0;",
        f"    for (round = 0; round < {CALLS}; ++round) {{",
        f"        for (i = 0; i < 16 * {size}; ++i) in[i / {size}][i % {size}] = next();",
    ]
    for f in manifest["functions"]:
        args = [f"in[{k}]" for k in range(len(f["inputs"]))]
        args += ["&params"] if f.get("reads_parameters") else []
        args += [f"out[{k}]" for k in range(len(f["outputs"]))]
        lines.append(f"        status |= {f['c_name']}({', '.join(args)});")
    if batched:
        lines.append("        if (round % 10 == 0) {")
    for f in batched:
        ports = f["inputs"] + f["outputs"]
        lines.append("            {")
        lines += [f"                double *b{k} = fresh({BATCH * max(1, _size(p))});" for k, p in enumerate(ports)]
        args = [f"b{k}" for k in range(len(f["inputs"]))]
        args += ["&params"] if f.get("reads_parameters") else []
        args += [f"b{len(f['inputs']) + k}" for k in range(len(f["outputs"]))]
        lines.append(f"                status |= {f['c_name']}_batch({BATCH}, {', '.join(args)});")
        lines += [f"                free(b{k});" for k in range(len(ports))]
        lines.append("            }")
    lines += ["        }"] if batched else []
    lines += ["    }", '    printf("done %d\\n", status);', "    return 0;", "}"]
    return "\n".join(lines) + "\n"


def _size(port: dict) -> int:
    n = 1
    for d in port["shape"]:
        n *= d
    return n


@pytest.mark.skipif(not COMPILERS, reason="no C compiler")
@pytest.mark.parametrize(
    "spec",
    [
        "two_link",
        "puma560",
        "styx_finger",
        "styx_high_ct",
        "styx_redundant",
        pytest.param("puma560_rmrc", marks=pytest.mark.slow),  # the PUMA's resolved-rate kernels: puma560's again
        "tripod_grasp",
        "styx_multirate",
    ],
)
def test_emitted_c_is_clean_under_sanitizers(tmp_path, spec):
    sanitized(tmp_path, spec, lanes=spec in LANES)


@pytest.mark.slow
@pytest.mark.skipif(not COMPILERS, reason="no C compiler")
def test_the_lanes_of_a_six_joint_arm_are_clean_under_sanitizers(tmp_path):
    sanitized(tmp_path, "puma560", lanes=True)


def sanitized(tmp_path: Path, spec: str, lanes: bool) -> None:
    """The spec's C and the harness under both sanitizers, built and run with each compiler."""
    out = tmp_path / spec
    assert main(["build", str(SPECS / f"{spec}.yaml"), "-o", str(out), "--no-compile", "-q"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    (tmp_path / "harness.c").write_text(harness(manifest))
    sources = [str(out / f"{manifest['name']}.c"), str(tmp_path / "harness.c")]
    exes = {cc: tmp_path / f"harness-{cc}" for cc in COMPILERS}
    started: list[subprocess.Popen] = []

    def start(command: list[str], **kwargs) -> subprocess.Popen:
        started.append(subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs))
        return started[-1]

    try:  # gcc's and clang's builds, then their runs, side by side (each is one process)
        flags = [] if lanes else ["-DRG_NO_LANES"]
        builds = {
            cc: start([cc, *SANITIZE, *flags, "-std=c99", f"-I{out}", *sources, "-lm", "-o", str(exe)])
            for cc, exe in exes.items()
        }
        for cc, build in builds.items():
            stderr = build.communicate()[1]
            if build.returncode != 0 and "sanitize" in stderr and "unsupported" in stderr.lower():
                pytest.skip(f"{cc} has no sanitizer runtime here: {stderr.strip()[:200]}")
            assert build.returncode == 0, stderr
        runs = {
            cc: start([str(exe)], env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
            for cc, exe in exes.items()
        }
        for cc, run in runs.items():
            stdout, stderr = run.communicate(timeout=600)
            assert run.returncode == 0 and stdout.startswith("done"), f"{cc}: {stderr[-3000:]}"
    finally:  # a skip or a failure leaves no process behind
        for process in started:
            if process.poll() is None:
                process.kill()
                process.communicate()


@pytest.mark.skipif(not COMPILERS, reason="no C compiler")
def test_the_sanitizers_see_a_planted_bug(tmp_path):
    """The flags above do catch what they are for: a use after free and a signed overflow."""
    for cc in COMPILERS:
        for body, finding in (
            ("double *p = malloc(4 * sizeof *p); free(p); return (int)p[argc];", "heap-use-after-free"),
            ("int x = 2147483647; x += argc; return x;", "overflow"),
        ):
            src = tmp_path / "bug.c"
            src.write_text(f"#include <stdlib.h>\nint main(int argc, char **argv) {{ (void)argv; {body} }}\n")
            exe = tmp_path / f"bug-{cc}"
            subprocess.run([cc, *SANITIZE, str(src), "-o", str(exe)], check=True, capture_output=True)
            run = subprocess.run([str(exe)], capture_output=True, text=True)
            assert run.returncode != 0 and finding in run.stderr, (cc, run.stderr[-500:])
