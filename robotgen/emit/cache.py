"""Content-hash cache: an unchanged spec is not rebuilt.

The key covers everything a build depends on: the spec (and the files it reads, such as a
URDF), the output options, robotgen's own code and templates, the CasADi version, the
compiler and $CFLAGS. It is stored beside the build in BUILD_KEY (not part of the emitted
sources, so generated/ stays byte-identical across robotgen edits that change nothing emitted)."""

from __future__ import annotations

import hashlib
import sysconfig
from importlib import metadata
from pathlib import Path

from robotgen.emit.compile import compiler, user_flags
from robotgen.emit.render import template_dir

BUILD_KEY = ".robotgen-build"
_PACKAGE = Path(__file__).resolve().parent.parent


def _code_files() -> list[Path]:
    return sorted(_PACKAGE.rglob("*.py")) + sorted(Path(template_dir()).glob("*.jinja"))


def build_key(inputs: list[Path], options: dict) -> str:
    """sha256 of everything a build depends on: its input files, options, robotgen's code and templates, CasADi, $CC
    and $CFLAGS."""
    h = hashlib.sha256()
    for path in inputs + _code_files():
        h.update(str(path.name).encode() + b"\0" + path.read_bytes() + b"\0")
    h.update(repr(sorted(options.items())).encode())
    h.update(metadata.version("casadi").encode())
    h.update(" ".join(compiler()).encode())  # $CC or Python's
    h.update(b"\0" + " ".join(user_flags()).encode())  # $CFLAGS
    return h.hexdigest()


def is_current(out_dir: Path, key: str, compiled: bool, name: str) -> bool:
    """Whether out_dir holds a build stamped with ``key`` (and, when ``compiled``, its extension module)."""
    stamp = out_dir / BUILD_KEY
    if not stamp.is_file() or stamp.read_text().strip() != key:
        return False
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    return not compiled or (out_dir / f"{name}{suffix}").is_file()


def record(out_dir: Path, key: str) -> None:
    """Stamp out_dir with the build key it was built under."""
    (out_dir / BUILD_KEY).write_text(key + "\n")
