"""The spec layer: a YAML spec file -> a validated RobotSystem, or located UserErrors."""

from __future__ import annotations

from robotgen.frontend.document import load_document
from robotgen.frontend.schema import schema_json, spec_schema
from robotgen.frontend.system import to_system
from robotgen.model.system import RobotSystem

__all__ = ["load_system", "schema_json", "spec_schema"]


def load_system(path: str) -> RobotSystem:
    """Read, validate and convert the spec at ``path``; raises robotgen.errors.UserErrors
    listing every problem (file, line, column) and never returns a half-valid system."""
    return to_system(load_document(path))
