"""Which files of an earlier build robotgen may delete when it replaces the output directory:
only those whose content proves that robotgen wrote them (docs/cli.md, "The output directory").

The earlier build's manifest.json must be a robotgen manifest (a module name, robotgen's
version, the sha256 of each emitted file, the C name of each function). Then, file by file:

- a file robotgen emits for that module (<name>.c, <name>.h, <name>_module.c, <name>.pyi,
  Makefile, <name>.pc.in, <name>Config.cmake.in) whose sha256 is the one the manifest lists;
- manifest.json itself, and .robotgen-build holding a build key (64 hexadecimal digits);
- the compiled extension <name>.*.so (or .pyd), and what the Makefile makes, <name>.o and
  lib<name>.a: binaries (ELF, Mach-O, PE/COFF, an ar archive, LLVM bitcode) that hold the C
  name of every function the manifest lists, the extension also PyInit_<name>. robotgen does
  not hash them (the extension is compiled after the manifest is written, make runs later),
  so their content is what proves them: the code of this module's functions.

Anything else (another file, a file of those names with other content, a directory, a
symbolic link) makes robotgen refuse; so does an input of the build inside the directory.
A planted or left-over manifest.json therefore decides nothing: the files it lists must
have the content it lists, and it can list only names robotgen writes."""

from __future__ import annotations

import json
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

from robotgen.emit.cache import BUILD_KEY
from robotgen.emit.render import TEMPLATES
from robotgen.model.names import PATTERN
from robotgen.output_files import MAX_PROVEN_BYTES, input_inside, refusal, sha256_of

MANIFEST = "manifest.json"
_STAMP = re.compile(rb"[0-9a-f]{64}\n?\Z")
_BINARY_MAGIC = (
    b"\x7fELF",
    b"\xfe\xed\xfa\xce",
    b"\xfe\xed\xfa\xcf",
    b"\xce\xfa\xed\xfe",
    b"\xcf\xfa\xed\xfe",
    b"\xca\xfe\xba\xbe",
    b"!<arch>\n",
    b"MZ",
    b"\x64\x86",
    b"\x64\xaa",
    b"\x4c\x01",
    b"BC\xc0\xde",
    b"\xde\xc0\x17\x0b",
)


@dataclass(frozen=True)
class Manifest:
    """What an earlier build's manifest.json says robotgen wrote."""

    name: str
    files: dict[str, str]  # emitted file -> sha256
    c_names: tuple[str, ...]  # every function's C name

    @staticmethod
    def read(directory: Path) -> Manifest | None:
        """The robotgen manifest in ``directory``, or None (absent, not a regular file, not
        robotgen's)."""
        path = directory / MANIFEST
        try:
            if not stat.S_ISREG(path.lstat().st_mode) or path.stat().st_size > MAX_PROVEN_BYTES:
                return None
            data = json.loads(path.read_text(encoding="utf-8"))
            name, files, functions = data["name"], data["files"], data["functions"]
            c_names = tuple(f["c_name"] for f in functions)
            if not (
                isinstance(name, str)
                and PATTERN.match(name)
                and isinstance(data["robotgen_version"], str)
                and isinstance(files, dict)
                and all(isinstance(v, str) for v in files.values())
                and c_names
                and all(isinstance(c, str) and c.startswith(f"{name}_") for c in c_names)
            ):
                return None
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            return None
        return Manifest(name, files, c_names)

    @property
    def emitted(self) -> set[str]:
        """The names of the files robotgen emits for this module."""
        return {file.format(name=self.name) for file in TEMPLATES}

    def is_extension(self, entry: str) -> bool:
        """Whether ``entry`` is the module's extension (<name>.so or .pyd, with or without an ABI tag)."""
        return bool(
            re.fullmatch(
                re.escape(self.name) + r"\.[A-Za-z0-9_.-]+\.(so|pyd)|" + re.escape(self.name) + r"\.(so|pyd)", entry
            )
        )

    def proves(self, path: Path) -> bool | None:
        """True: robotgen wrote ``path`` (or its Makefile made it); False: a file of a name
        robotgen writes whose content is not what it wrote; None: a name robotgen never
        writes here, or not a regular file."""
        entry = path.name
        try:
            if not stat.S_ISREG(path.lstat().st_mode):
                return None
        except OSError:
            return None
        if entry == MANIFEST:
            return True  # read and checked as robotgen's
        if entry == BUILD_KEY:
            return path.stat().st_size <= 65 and bool(_STAMP.match(path.read_bytes()))
        if entry in self.emitted:
            return entry in self.files and sha256_of(path) == self.files[entry]
        binary = self.is_extension(entry)
        if binary or entry in (f"{self.name}.o", f"lib{self.name}.a"):
            return self._binary_of_module(path, extension=binary)
        return None

    def _binary_of_module(self, path: Path, extension: bool) -> bool:
        if path.stat().st_size > MAX_PROVEN_BYTES:
            return False
        data = path.read_bytes()
        names = [*self.c_names, *([f"PyInit_{self.name}"] if extension else [])]
        return data.startswith(_BINARY_MAGIC) and all(n.encode() in data for n in names)


def replace_problem(out_dir: Path, inputs: tuple[Path, ...] = ()) -> str | None:
    """Why ``out_dir`` may not be replaced by a build, or None: only a missing or empty
    directory, or an earlier robotgen output every file of which robotgen can prove it wrote
    (module docstring), is ever replaced; never the current directory or one that contains
    it, nor one holding an input of the build. OSErrors are the caller's (OutputError)."""
    out_dir = Path(out_dir)
    if out_dir.is_symlink() or (out_dir.exists() and not out_dir.is_dir()):
        return f"{out_dir} exists and is not a directory"
    if not out_dir.exists():
        return None
    here = Path.cwd().resolve()
    if out_dir.resolve() == here or out_dir.resolve() in here.parents:
        return f"{out_dir} is the current directory or contains it; choose an output directory below it"
    problem = input_inside(out_dir, inputs)
    if problem:
        return problem
    entries = sorted(p.name for p in out_dir.iterdir())
    if not entries:
        return None
    manifest = Manifest.read(out_dir)
    if manifest is None:
        return f"{out_dir} is not empty and is not a robotgen output (no robotgen {MANIFEST}); refusing to replace it"
    verdicts = {entry: manifest.proves(out_dir / entry) for entry in entries}
    return refusal(
        out_dir,
        [e for e, v in verdicts.items() if v is None],
        [e for e, v in verdicts.items() if v is False],
        "replace it",
    )


def remove_written(directory: Path) -> list[str]:
    """Deletes what robotgen can prove it wrote in ``directory`` (an earlier output, renamed
    aside by the swap), then the directory if that emptied it; returns what was left (files
    that appeared after the last check), directory and all."""
    manifest = Manifest.read(directory)
    left = []
    for path in sorted(directory.iterdir()):
        if manifest is not None and manifest.proves(path) and path.name != MANIFEST:
            path.unlink()
        elif path.name != MANIFEST:
            left.append(path.name)
    if not left:
        (directory / MANIFEST).unlink(missing_ok=True)
        os.rmdir(directory)
    return left
