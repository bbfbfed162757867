"""`-o DIR` replaces only what robotgen wrote: a user's folder that happens to hold a
manifest.json, the current directory or one of its parents is refused (exit 1) and left as it
was; an earlier output, also after `make` ran in it, is replaced."""

from __future__ import annotations

import errno
import hashlib
import json
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


def _earlier_output(out, **changes) -> dict:
    """A build of two_link in ``out`` with its manifest changed by ``changes`` (key -> value,
    "files" merged): what a planted or left-over manifest.json says."""
    assert build(out) == 0
    (out / ".robotgen-build").unlink()
    manifest = json.loads((out / "manifest.json").read_text())
    files = {**manifest["files"], **changes.pop("files", {})}
    manifest.update(changes, files=files)
    (out / "manifest.json").write_text(json.dumps(manifest))
    return manifest


def _left_alone(out, err: str, names: list[str], before: dict) -> None:
    assert all(name in err for name in names), err
    assert {p.name: (p.read_bytes() if p.is_file() else "dir") for p in out.iterdir()} == before
    assert not [p for p in out.parent.iterdir() if ".tmp-" in p.name or ".old-" in p.name]


def _contents(out) -> dict:
    return {p.name: (p.read_bytes() if p.is_file() else "dir") for p in out.iterdir()}


@pytest.mark.parametrize("what", ["file", "subdirectory", "file with its own hash"])
def test_a_planted_manifest_decides_nothing(tmp_path, capsys, what):
    """{"files": {"thesis.tex": "0"}} in the manifest once made robotgen delete thesis.tex
    (exit 0): the hashes were never checked, and any name was taken. Even the right hash does
    not make a name robotgen never writes its own."""
    out = tmp_path / "gen"
    text = b"three years of work"
    digest = hashlib.sha256(text).hexdigest()
    _earlier_output(out, files={"thesis.tex": digest if what == "file with its own hash" else "0"})
    if what == "subdirectory":
        (out / "thesis.tex").mkdir()
        (out / "thesis.tex" / "chapter1.tex").write_bytes(text)
    else:
        (out / "thesis.tex").write_bytes(text)
    before = _contents(out)
    assert build(out) == 1
    _left_alone(out, capsys.readouterr().err, ["robotgen did not write (thesis.tex)"], before)
    if what == "subdirectory":
        assert (out / "thesis.tex" / "chapter1.tex").read_bytes() == text


def test_the_spec_inside_the_output_directory_is_never_touched(tmp_path, capsys):
    out = tmp_path / "gen"
    _earlier_output(out, files={"arm.yaml": "0"})
    spec = out / "arm.yaml"
    spec.write_text(Path(SPEC).read_text())
    before = _contents(out)
    assert main(["build", str(spec), "-o", str(out), "--no-compile", "-q"]) == 1
    _left_alone(out, capsys.readouterr().err, [f"holds {spec}, which this command reads"], before)
    out2 = tmp_path / "empty"
    out2.mkdir()
    (out2 / "arm.yaml").write_text(Path(SPEC).read_text())  # the spec alone in the directory
    assert main(["build", str(out2 / "arm.yaml"), "-o", str(out2), "--no-compile", "-q"]) == 1
    assert (out2 / "arm.yaml").read_text() == Path(SPEC).read_text()


@pytest.mark.parametrize("manifest_files", ["empty", "genuine"])
def test_files_that_share_a_name_with_robotgens_are_not_its_own(tmp_path, capsys, manifest_files):
    """two_link.o and libtwo_link.a of the user's (under an empty manifest, or beside a real
    output) are not what the Makefile makes: they hold none of the module's functions."""
    out = tmp_path / "gen"
    if manifest_files == "empty":
        _earlier_output(out)
        manifest = json.loads((out / "manifest.json").read_text())
        for name in manifest["files"]:
            (out / name).unlink()
        manifest["files"] = {}
        (out / "manifest.json").write_text(json.dumps(manifest))
    else:
        _earlier_output(out)
    (out / "two_link.o").write_bytes(b"\x7fELF my own object")
    (out / "libtwo_link.a").write_text("my notes, named like a library")
    before = _contents(out)
    assert build(out) == 1
    _left_alone(out, capsys.readouterr().err, ["two_link.o", "libtwo_link.a"], before)


def test_an_edited_output_file_is_not_replaced(tmp_path, capsys):
    out = tmp_path / "gen"
    _earlier_output(out)
    with open(out / "two_link.c", "a") as f:
        f.write("/* my fix */\n")
    before = _contents(out)
    assert build(out) == 1
    _left_alone(out, capsys.readouterr().err, ["changed since robotgen wrote them (two_link.c)"], before)


def test_a_file_that_comes_in_during_the_build_is_kept(tmp_path, capsys, monkeypatch):
    """The directory is checked again just before the swap (the graphs take seconds)."""
    out = tmp_path / "gen"
    _earlier_output(out)
    import robotgen.symbolic

    real = robotgen.symbolic.module_extras

    def meanwhile(system):
        (out / "notes.txt").write_text("written while robotgen built the graphs")
        return real(system)

    monkeypatch.setattr(robotgen.symbolic, "module_extras", meanwhile)
    assert build(out) == 1
    assert "robotgen did not write (notes.txt)" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "written while robotgen built the graphs"
    assert (out / "two_link.c").exists()


def test_only_what_robotgen_wrote_is_removed_from_the_old_output(tmp_path):
    """What comes in between the last check and the rename stays, with the manifest."""
    from robotgen.emit.output_directory import remove_written

    old = tmp_path / "old"
    _earlier_output(old)
    (old / ".robotgen-build").write_text("ab" * 32 + "\n")
    (old / "late.txt").write_text("late")
    assert remove_written(old) == ["late.txt"]
    assert sorted(p.name for p in old.iterdir()) == ["late.txt", "manifest.json"]
    (old / "late.txt").unlink()
    _earlier_output(tmp_path / "other")
    assert remove_written(tmp_path / "other") == [] and not (tmp_path / "other").exists()


def test_an_earlier_compiled_output_is_proven_by_its_content(tmp_path):
    """The extension and make's object and library hold every function of the module."""
    from robotgen.emit.output_directory import Manifest

    out = tmp_path / "gen"
    assert main(["build", SPEC, "-o", str(out), "-q"]) == 0
    subprocess.run(["make", "-C", str(out)], check=True, capture_output=True)
    manifest = Manifest.read(out)
    extension = next(p for p in out.iterdir() if p.suffix in (".so", ".pyd"))
    for path in (extension, out / "two_link.o", out / "libtwo_link.a"):
        assert manifest.proves(path) is True, path
    (out / "two_link.o").write_bytes((out / "two_link.o").read_bytes().replace(b"two_link_mass", b"two_link_MASS"))
    assert manifest.proves(out / "two_link.o") is False


@pytest.mark.parametrize("case", ["through a file", "name too long", "rename refused"])
def test_output_directory_errors_are_the_users(tmp_path, capsys, monkeypatch, case):
    """NotADirectoryError, OSError 36 and a PermissionError (an immutable directory) were
    internal errors (exit 3)."""
    (tmp_path / "file.txt").write_text("x")
    out = {
        "through a file": tmp_path / "file.txt" / "out",
        "name too long": tmp_path / ("x" * 300),
        "rename refused": tmp_path / "gen",
    }[case]
    if case == "rename refused":
        assert build(out) == 0
        (out / ".robotgen-build").unlink()
        before = _contents(out)

        def refused(self, target):
            raise PermissionError(errno.EPERM, "Operation not permitted", str(self))

        monkeypatch.setattr(Path, "rename", refused)
    assert build(out) == 1
    err = capsys.readouterr().err
    words = {
        "through a file": f"{tmp_path / 'file.txt'} is a file, not a directory",
        "name too long": "File name too long",
        "rename refused": "Operation not permitted",
    }[case]
    assert err.startswith(f"robotgen: error: cannot write the output directory {out}: ") and words in err, err
    if case == "rename refused":
        monkeypatch.undo()
        assert _contents(out) == before
        assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name or ".old-" in p.name]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_a_directory_without_permission_is_the_users(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        assert build(locked / "out") == 1
    finally:
        locked.chmod(0o700)
    assert "Permission denied" in capsys.readouterr().err
