"""The emitted C of the examples, double and float, compiled for a Cortex-M7 with the Arm GNU
toolchain (Debian's gcc-arm-none-eabi): warning-free under -Wall -Wextra -Werror
-Wdouble-promotion, no data or bss (no globals), nothing called but <math.h> functions (no
memset or memcpy but where a controller struct zeroes or copies its state), every function's
stack use static. Prints code size and stack per function;
`robotgen build --target cortex-m7` puts the same numbers in manifest.json."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from robotgen.cli import main
from robotgen.emit.targets import TARGETS

SPECS = Path(__file__).resolve().parents[2] / "specs"
CC = shutil.which("arm-none-eabi-gcc")
FLAGS = [*TARGETS["cortex-m7"][1], "-fstack-usage"]  # what `--target cortex-m7` compiles with
MATH = {
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "atan2",
    "exp",
    "log",
    "sqrt",
    "tanh",
    "sinh",
    "cosh",
    "pow",
    "fabs",
    "fmin",
    "fmax",
    "copysign",
    "floor",
    "ceil",
    "remainder",
}


# every spec in both precisions; the resolved-rate PUMA and the adaptive one in float are the
# suite's slowest cross-compiles (`make test-slow` runs them)
SLOW_CORTEX_M = {("puma560_rmrc", "double"), ("puma560_rmrc", "float"), ("puma560_rmac", "float")}
CORTEX_M_CASES = [
    pytest.param(spec, precision, marks=pytest.mark.slow) if (spec, precision) in SLOW_CORTEX_M else (spec, precision)
    for spec in ("puma560", "styx_high_ct", "puma560_rmrc", "puma560_rmac", "styx_multirate")
    for precision in ("double", "float")
]


@pytest.mark.skipif(CC is None, reason="arm-none-eabi-gcc is not installed (Debian: apt-get install gcc-arm-none-eabi)")
@pytest.mark.parametrize("spec,precision", CORTEX_M_CASES)
def test_cortex_m7_build(tmp_path, monkeypatch, spec, precision):
    monkeypatch.chdir(tmp_path)
    # the C alone first; it compiles here while robotgen builds it again and compiles it for
    # the target (one process each, side by side)
    plain = tmp_path / "plain"
    assert (
        main(["build", str(SPECS / f"{spec}.yaml"), "-o", str(plain), "--precision", precision, "--no-compile", "-q"])
        == 0
    )
    obj = tmp_path / f"{spec}.o"
    compiling = subprocess.Popen(
        [CC, *FLAGS, "-c", str(plain / f"{spec}.c"), "-o", str(obj)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    out = Path(spec)  # relative, as a user types it
    try:
        assert (
            main(
                [
                    "build",
                    str(SPECS / f"{spec}.yaml"),
                    "-o",
                    str(out),
                    "--precision",
                    precision,
                    "--no-compile",
                    "--target",
                    "cortex-m7",
                    "-q",
                ]
            )
            == 0
        )
    finally:
        stderr = compiling.communicate()[1]
    assert compiling.returncode == 0, stderr
    assert (out / f"{spec}.c").read_bytes() == (plain / f"{spec}.c").read_bytes()
    size = subprocess.run(["arm-none-eabi-size", str(obj)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(v) for v in size.splitlines()[1].split()[:3])
    assert data == 0 and bss == 0, size
    undefined = set(
        subprocess.run(["arm-none-eabi-nm", "-u", str(obj)], capture_output=True, text=True, check=True).stdout.split()
    ) - {"U"}
    suffix = "f" if precision == "float" else ""
    # gcc asks any freestanding environment for memcpy, memmove, memset and memcmp: it turns the
    # loops that zero and copy a controller's state (the adaptive law's: 5.6 kB; a multi-rate tree's
    # struct, copied whole so that a failed step changes nothing) into calls to them
    assert undefined <= {f + suffix for f in MATH} | {"memcpy", "memset"}, undefined
    for f, (called, tail) in _callees(obj).items():
        assert not (called | tail) & {"memcpy", "memset"} or re.fullmatch(
            r"\w+_(controller|multirate)_(reset|step)", f
        ), (f, called, tail)
    symbols = subprocess.run(
        ["arm-none-eabi-nm", "-S", "--size-sort", str(obj)], capture_output=True, text=True, check=True
    ).stdout
    code = {line.split()[3]: int(line.split()[1], 16) for line in symbols.splitlines() if line.split()[2] in "Tt"}
    stack = {}
    for line in (tmp_path / f"{spec}.su").read_text().splitlines():
        match = re.match(r".*:([\w.]+)\t(\d+)\t(\w+)", line)  # gcc's split-off parts: f.part.0
        assert match and match.group(3) == "static", line  # no variable-length stack
        stack[match.group(1)] = int(match.group(2))
    print(f"\n{spec} ({precision}) on Cortex-M7: {text} bytes of code")
    for name in sorted(code):
        print(f"  {name:50s} {code[name]:7d} B code {stack.get(name, 0):6d} B stack")
    assert set(code) == set(stack)
    if spec == "puma560_rmac":  # the step's identification and control, the reset's series: loops
        for kernel, most in (("step", 40_000), ("init", 75_000)):  # straight-line 75 and 134 kB
            size = sum(v for f, v in code.items() if re.fullmatch(rf"{spec}_adaptive_{kernel}(\.part\.\d+)?", f))
            assert size < most, (kernel, size)
    # the manifest's report is these numbers (same compiler, same flags)
    report = json.loads((out / "manifest.json").read_text())["targets"]["cortex-m7"]
    assert (report["text_bytes"], report["data_bytes"], report["bss_bytes"]) == (text, 0, 0)
    assert {f: (v["code_bytes"], v["stack_bytes"]) for f, v in report["functions"].items()} == {
        f: (code[f], stack[f]) for f in code
    }
    callees, functions = _callees(obj), report["functions"]

    def deepest(names: set[str]) -> int:
        return max((functions[g]["stack_bytes_with_calls"] for g in names if g in stack), default=0)

    for f, v in functions.items():  # a call adds the callee's frames; a tail call replaces f's own
        called, tail = callees[f]
        assert v["stack_bytes_with_calls"] == max(stack[f] + deepest(called), deepest(tail)), f
    for f in functions:  # gcc splits f.part.N off f only to call it from f, by bl or by a tail b
        parts = {g for g in functions if re.fullmatch(re.escape(f) + r"\.part\.\d+", g)}
        assert functions[f]["stack_bytes_with_calls"] >= deepest(parts), f


def _callees(obj: Path) -> dict[str, tuple[set[str], set[str]]]:
    """The functions each function calls (bl) and tail-calls (b to another function)."""
    listing = subprocess.run(
        ["arm-none-eabi-objdump", "-d", str(obj)], capture_output=True, text=True, check=True
    ).stdout
    callees = {}
    for block in listing.split("\n\n"):
        header = re.match(r"[0-9a-f]+ <([\w.]+)>:", block)
        if header:
            name = header.group(1)
            branches = re.findall(r"\s(bl|b\w{0,2}(?:\.[nw])?)\s+[0-9a-f]+ <([\w.]+?)(?:\+0x[0-9a-f]+)?>", block)
            callees[name] = (
                {g for op, g in branches if op == "bl" and g != name},
                {g for op, g in branches if op != "bl" and g != name},
            )
    return callees


def test_target_without_its_compiler_is_the_users_to_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))  # no arm-none-eabi-gcc here
    out = tmp_path / "out"
    assert (
        main(["build", str(SPECS / "two_link.yaml"), "-o", str(out), "--target", "cortex-m7", "--no-compile", "-q"])
        == 1
    )
    assert "arm-none-eabi-gcc" in capsys.readouterr().err and not out.exists()
