"""Renders the templates/ layouts (one per emitted file) from a ``ModuleView``."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import jinja2

from robotgen.emit.context import ModuleView

_PACKAGE = Path(__file__).resolve().parent.parent
# A source checkout keeps templates/ beside robotgen/; a wheel ships it as robotgen/templates.
_TEMPLATE_DIRS = (_PACKAGE / "templates", _PACKAGE.parent / "templates")

# emitted file name (with {name}) -> template
TEMPLATES = {
    "{name}.h": "header.h.jinja",
    "{name}.c": "source.c.jinja",
    "{name}_module.c": "pymodule.c.jinja",
    "{name}.pyi": "stub.pyi.jinja",
    "Makefile": "Makefile.jinja",
    "{name}.pc.in": "pkgconfig.pc.in.jinja",
    "{name}Config.cmake.in": "cmake_config.cmake.in.jinja",
}


def template_dir() -> Path:
    """The directory of the jinja2 templates: robotgen/templates when installed, templates/ in a checkout."""
    for candidate in _TEMPLATE_DIRS:
        if (candidate / "header.h.jinja").is_file():
            return candidate
    raise RuntimeError("robotgen's templates are missing; looked in " + ", ".join(str(d) for d in _TEMPLATE_DIRS))


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The jinja2 environment every template renders in: strict undefined names, no escaping, trimmed blocks."""
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        autoescape=False,
    )


def render_all(view: ModuleView) -> dict[str, str]:
    """File name -> text, for every templated file of the module."""
    env = environment()
    return {
        file.format(name=view.name): env.get_template(template).render(m=view) for file, template in TEMPLATES.items()
    }
