"""The emitted C library as a package: its Makefile honours CC/CFLAGS/AR/PREFIX/DESTDIR, and
`make install` gives a pkg-config file and a CMake package that build working programs,
whose numbers equal the Python module's."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robotgen.cli import main
from robotgen.emit.compile import extension_suffix

ROOT = Path(__file__).resolve().parents[2]
NAME = "two_link"
GCC = shutil.which("gcc")
PKG_CONFIG = shutil.which("pkg-config")
CMAKE = shutil.which("cmake")
pytestmark = pytest.mark.skipif(GCC is None or shutil.which("make") is None, reason="gcc and make are required")
Q = (0.3, -0.75)

APP = f"""#include <stdio.h>
#include <{NAME}.h>

int main(void)
{{
    const double q[{NAME.upper()}_NQ] = {{{Q[0]!r}, {Q[1]!r}}};
    double m[{NAME.upper()}_MASS_MASS_SIZE];
    int i;
    if ({NAME}_mass(q, m) != 0) {{
        return 1;
    }}
    for (i = 0; i < {NAME.upper()}_MASS_MASS_SIZE; ++i) {{
        printf("%.17g\\n", m[i]);
    }}
    return 0;
}}
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("packaging") / NAME
    assert main(["build", str(ROOT / "specs" / f"{NAME}.yaml"), "-o", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def python_mass(built) -> np.ndarray:
    """The Python module's mass(Q), loaded without touching sys.modules."""
    spec = importlib.util.spec_from_file_location(NAME, built / (NAME + extension_suffix()))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    mass = module.mass(np.array(Q))
    np.testing.assert_array_equal(module.mass(q=np.array(Q)), mass)
    assert mass.shape == (2, 2) and np.all(np.abs(mass) > 1e-3)
    return mass


def copy_of(built: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(built, tmp_path / "lib", ignore=shutil.ignore_patterns("*.so")))


def make(directory: Path, *args: str, env: dict | None = None) -> str:
    """Runs make in ``directory`` with a clean make environment; returns its output."""
    clean = {
        k: v
        for k, v in os.environ.items()
        if k not in ("CC", "CFLAGS", "CPPFLAGS", "AR", "PREFIX", "DESTDIR", "MAKEFLAGS")
    }
    result = subprocess.run(
        ["make", "-C", str(directory), *args], env={**clean, **(env or {})}, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def compile_line(output: str) -> list[str]:
    [line] = [line for line in output.splitlines() if f"-c -o {NAME}.o" in line]
    return line.split()


def run_app(executable: Path) -> np.ndarray:
    result = subprocess.run([str(executable)], capture_output=True, text=True, check=True)
    return np.array([float(v) for v in result.stdout.split()]).reshape(2, 2)


# ----------------------------------------------------------------------------- the Makefile


def test_make_honours_cc_and_cflags(built, tmp_path):
    lib = copy_of(built, tmp_path)
    words = compile_line(make(lib, "CC=gcc", "CFLAGS=-O1"))
    assert words[0] == "gcc" and "-O1" in words and "-std=c99" in words
    assert "-Werror" not in words and "-O2" not in words  # CFLAGS replaced the defaults
    assert (lib / f"lib{NAME}.a").is_file()
    subprocess.run(["nm", str(lib / f"lib{NAME}.a")], check=True, capture_output=True)


def test_make_defaults_are_strict_and_c99_is_always_added(built, tmp_path):
    lib = copy_of(built, tmp_path)
    words = compile_line(make(lib, "-n"))
    assert {"-O2", "-Wall", "-Wextra", "-Werror", "-std=c99"} <= set(words)
    words = compile_line(
        make(lib, "-n", env={"CC": "gcc", "CFLAGS": "-O0 -g -std=gnu11", "CPPFLAGS": "-DROBOT=1", "AR": "gcc-ar"})
    )
    assert words[0] == "gcc" and {"-O0", "-g", "-DROBOT=1"} <= set(words)
    assert words.index("-std=c99") > words.index("-std=gnu11")  # C99 wins
    assert f"gcc-ar rcs lib{NAME}.a {NAME}.o" in make(lib, "-n", "AR=gcc-ar")


def test_install_with_destdir_writes_the_final_prefix(built, tmp_path):
    lib = copy_of(built, tmp_path)
    stage = tmp_path / "stage"
    make(lib, "install", "PREFIX=/opt/robots", f"DESTDIR={stage}")
    root = stage / "opt" / "robots"
    assert sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()) == [
        "include/two_link.h",
        f"lib/cmake/{NAME}/{NAME}Config.cmake",
        f"lib/lib{NAME}.a",
        f"lib/pkgconfig/{NAME}.pc",
    ]
    pc = (root / "lib" / "pkgconfig" / f"{NAME}.pc").read_text()
    assert "prefix=/opt/robots\n" in pc and "@" not in pc and str(stage) not in pc
    config = (root / "lib" / "cmake" / NAME / f"{NAME}Config.cmake").read_text()
    assert '"/opt/robots/lib/libtwo_link.a"' in config and '"/opt/robots/include"' in config
    assert (root / "include" / f"{NAME}.h").read_bytes() == (built / f"{NAME}.h").read_bytes()
    make(lib, "uninstall", "PREFIX=/opt/robots", f"DESTDIR={stage}")
    assert not [p for p in root.rglob("*") if p.is_file()]


# ------------------------------------------------------------------------- installed library


@pytest.fixture(scope="module")
def prefix(built, tmp_path_factory) -> Path:
    """`make install PREFIX=...` of a build made with the environment's CC and CFLAGS."""
    base = tmp_path_factory.mktemp("installed")
    lib = copy_of(built, base)
    prefix = base / "prefix"
    make(lib, "install", f"PREFIX={prefix}", env={"CC": GCC, "CFLAGS": "-O2 -Wall"})
    shutil.rmtree(lib)  # programs must find everything in the install alone
    return prefix


@pytest.mark.skipif(PKG_CONFIG is None, reason="pkg-config not installed")
def test_pkg_config_flags_build_a_program_that_agrees_with_python(prefix, python_mass, tmp_path):
    env = {**os.environ, "PKG_CONFIG_PATH": str(prefix / "lib" / "pkgconfig")}
    flags = subprocess.run(
        [PKG_CONFIG, "--cflags", "--libs", NAME], env=env, check=True, capture_output=True, text=True
    ).stdout.split()
    assert flags == [f"-I{prefix}/include", f"-L{prefix}/lib", f"-l{NAME}", "-lm"]
    variable = subprocess.run(
        [PKG_CONFIG, "--variable=prefix", NAME], env=env, check=True, capture_output=True, text=True
    ).stdout.strip()
    assert variable == str(prefix)
    (tmp_path / "app.c").write_text(APP)
    subprocess.run(
        [GCC, "-std=c99", "-Wall", "-Wextra", "-Werror", str(tmp_path / "app.c"), "-o", str(tmp_path / "app"), *flags],
        check=True,
        capture_output=True,
    )
    np.testing.assert_allclose(run_app(tmp_path / "app"), python_mass, rtol=1e-13, atol=0)


@pytest.mark.skipif(CMAKE is None, reason="cmake not installed")
def test_cmake_find_package_builds_a_program_that_agrees_with_python(prefix, python_mass, tmp_path):
    app = tmp_path / "app"
    app.mkdir()
    (app / "app.c").write_text(APP)
    (app / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.10)\n"
        "project(app C)\n"
        f"find_package({NAME} REQUIRED)\n"
        "add_executable(app app.c)\n"
        f"target_link_libraries(app PRIVATE {NAME}::{NAME})\n"
    )
    build = tmp_path / "build"
    for command in (
        [CMAKE, "-S", str(app), "-B", str(build), f"-DCMAKE_PREFIX_PATH={prefix}", f"-DCMAKE_C_COMPILER={GCC}"],
        [CMAKE, "--build", str(build)],
    ):
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stdout + result.stderr
    np.testing.assert_allclose(run_app(build / "app"), python_mass, rtol=1e-13, atol=0)
