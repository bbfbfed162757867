"""The pieces the spec's JSON Schema is written in (robotgen.frontend.schema): numbers that may
be constant expressions, weights, vectors, closed objects. A law's settings block
(robotgen.model.laws.registry: its ``schema``) is written in them too."""

from __future__ import annotations

IDENTIFIER = "^[A-Za-z_][A-Za-z0-9_]*$"


def number(description: str, **bounds: float) -> dict:
    """A YAML number or a string holding a constant expression; bounds apply to numbers."""
    return {"type": ["number", "string"], "description": description, **bounds}


def parameter(description: str, **bounds: float) -> dict:
    """A number, or {runtime: number}: a run-time parameter with that default."""
    return {
        "type": ["number", "string", "object"],
        "description": f"{description}; {{runtime: value}} makes it a run-time parameter",
        "properties": {"runtime": {"$ref": "#/$defs/number"}},
        "required": ["runtime"],
        "additionalProperties": False,
        **bounds,
    }


def numbers(description: str) -> dict:
    """A list of numbers, each a YAML number or a constant expression."""
    return {"type": "array", "items": {"$ref": "#/$defs/number"}, "description": description}


def weights(description: str) -> dict:
    """Schema of a weight: one number, or a list of numbers (a diagonal)."""
    return {"type": ["number", "string", "array"], "items": {"$ref": "#/$defs/number"}, "description": description}


def weight_matrix(description: str) -> dict:
    """Schema of a weight matrix: one number, a diagonal list, or a list of rows."""
    return {
        "type": ["number", "string", "array"],
        "description": description,
        "items": {"anyOf": [{"$ref": "#/$defs/number"}, {"type": "array", "items": {"$ref": "#/$defs/number"}}]},
    }


def vector3(description: str) -> dict:
    """Schema of a 3-vector of numbers."""
    return {
        "type": "array",
        "description": description,
        "minItems": 3,
        "maxItems": 3,
        "items": {"$ref": "#/$defs/number"},
    }


def vector2(description: str) -> dict:
    """Schema of a 2-vector of numbers."""
    return {
        "type": "array",
        "description": description,
        "minItems": 2,
        "maxItems": 2,
        "items": {"$ref": "#/$defs/number"},
    }


def names(description: str, **bounds: int) -> dict:
    """Schema of a list of identifiers (``bounds``: minItems, maxItems)."""
    return {"type": "array", "description": description, "items": {"type": "string", "pattern": IDENTIFIER}, **bounds}


def expressions(description: str, **bounds: int) -> dict:
    """Schema of a list of expressions in the spec's symbols (``bounds``: minItems, maxItems)."""
    return {"type": "array", "description": description, "items": {"$ref": "#/$defs/expression"}, **bounds}


def expression_matrix(description: str) -> dict:
    """Schema of a matrix of expressions, as a list of rows."""
    return {
        "type": "array",
        "description": description,
        "minItems": 1,
        "items": {"type": "array", "items": {"$ref": "#/$defs/expression"}},
    }


def closed_object(description: str, properties: dict, required: tuple[str, ...] = ()) -> dict:
    """Schema of an object with these properties and no others; ``required`` must be present."""
    schema = {"type": "object", "description": description, "additionalProperties": False, "properties": properties}
    if required:
        schema["required"] = list(required)
    return schema


def exactly_one_of(keys: tuple[str, ...]) -> list[dict]:
    """The ``oneOf`` clauses that make exactly one of ``keys`` present."""
    return [{"required": [key]} for key in keys]
