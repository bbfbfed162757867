"""`-o DIR` replaces only what robotgen wrote: a user's folder that happens to hold a
manifest.json, the current directory or one of its parents is refused (exit 1) and left as it
was; an earlier output, also after `make` ran in it, is replaced."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from robotgen.cli import main

SPEC = str(Path(__file__).resolve().parents[2] / "specs" / "two_link.yaml")


def build(out) -> int:
    return main(["build", SPEC, "-o", str(out), "--no-compile", "-q"])


def test_a_users_folder_with_a_manifest_is_left_alone(tmp_path, capsys):
    out = tmp_path / "mine"
    assert build(out) == 0
    (out / "thesis.tex").write_text("three years of work")
    (out / ".robotgen-build").unlink()  # the spec unchanged would otherwise be "up to date"
    assert build(out) == 1
    assert "robotgen did not write (thesis.tex)" in capsys.readouterr().err
    assert (out / "thesis.tex").read_text() == "three years of work"


def test_a_foreign_manifest_is_not_robotgens(tmp_path, capsys):
    out = tmp_path / "data"
    out.mkdir()
    (out / "manifest.json").write_text('{"files": ["a.csv"]}')
    (out / "a.csv").write_text("1,2\n")
    assert build(out) == 1
    assert "is not a robotgen output" in capsys.readouterr().err
    assert (out / "a.csv").exists()


@pytest.mark.parametrize("target", [".", ".."])
def test_the_current_directory_and_its_parents_are_refused(tmp_path, capsys, target):
    here = tmp_path / "work"
    here.mkdir()
    cwd = os.getcwd()
    try:
        os.chdir(here)
        assert build(target) == 1
    finally:
        os.chdir(cwd)
    assert "current directory" in capsys.readouterr().err
    assert here.is_dir()


def test_an_earlier_output_is_replaced_also_after_make(tmp_path):
    out = tmp_path / "gen"
    assert main(["build", SPEC, "-o", str(out), "-q"]) == 0
    subprocess.run(["make", "-C", str(out)], check=True, capture_output=True)
    assert (out / "libtwo_link.a").exists()
    (out / ".robotgen-build").unlink()
    assert build(out) == 0
