"""pydantic's error list -> one line naming the config key and what is allowed (`ncbot.pipelines.config` raises it as a
`ValueError`; the CLI prints it and exits 2). Light: pydantic only, no torch.
"""
from __future__ import annotations

import types
import typing
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo


def _type_name(annotation: Any) -> str:
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return _type_name(typing.get_args(annotation)[0])
    if origin is Literal:
        return "one of " + ", ".join(repr(v) for v in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(annotation))
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"a mapping of {', '.join(annotation.model_fields)}"
    if origin is list:
        return f"a list of {_type_name(typing.get_args(annotation)[0])}"
    if origin is dict:
        return "a mapping"
    return {int: "an integer", float: "a number", bool: "true/false", str: "a string"}.get(annotation, str(annotation))


def _bounds(annotation: Any, field: FieldInfo | None = None) -> str:
    """The range constraints of a field, e.g. '> 0' or 'between 0 and 1'."""
    metadata = list(field.metadata) if field is not None else []
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):  # `Positive | None`: the number's bounds
        annotation = next(a for a in typing.get_args(annotation) if a is not type(None))
    while typing.get_origin(annotation) is Annotated:
        annotation, *extra = typing.get_args(annotation)
        metadata += [m for item in extra for m in (item.metadata if isinstance(item, FieldInfo) else [item])]
    limits = {key: getattr(m, key) for m in metadata for key in ("gt", "ge", "lt", "le") if getattr(m, key, None) is not None}
    if "ge" in limits and "le" in limits:
        return f"between {_number(limits['ge'])} and {_number(limits['le'])}"
    symbols = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}
    return " and ".join(f"{symbols[key]} {_number(value)}" for key, value in limits.items())


def _number(value: float) -> str:
    """A bound as people write it: 65536, 0.5 (no 6.5e+04)."""
    return str(value) if isinstance(value, int) else f"{value:g}"


def _describe(loc: tuple[Any, ...], root: type[BaseModel]) -> tuple[str, Any, FieldInfo | None, type[BaseModel]]:
    """Walk an error location through the models from `root`: (dotted key, its annotation, its field, the model
    holding it)."""
    model: type[BaseModel] = root
    key, annotation, field = "", None, None
    for part in loc:
        if annotation is None:
            if part not in model.model_fields:
                return f"{key}.{part}" if key else str(part), None, None, model
            field = model.model_fields[part]
            key = f"{key}.{part}" if key else str(part)
            annotation = field.annotation
            if typing.get_origin(annotation) in (typing.Union, types.UnionType) and loc[-1] != part:  # `Section | None`
                annotation = next(a for a in typing.get_args(annotation) if a is not type(None))
            if isinstance(annotation, type) and issubclass(annotation, BaseModel):
                model, annotation, field = annotation, None, None
        elif isinstance(part, int):
            while typing.get_origin(annotation) is Annotated:
                annotation = typing.get_args(annotation)[0]
            if typing.get_origin(annotation) is not list:
                break
            key, annotation, field = f"{key}[{part}]", typing.get_args(annotation)[0], None
    return key, annotation, field, model


def validation_line(error: ValidationError, root: type[BaseModel]) -> str:
    """The first problem pydantic found validating the model `root`, as the one line the CLI prints."""
    first = error.errors(include_url=False)[0]
    kind, loc, value = first["type"], first["loc"], first.get("input")
    if kind == "value_error":  # raised by a validator above with its own sentence
        return str(first["ctx"]["error"])
    key, annotation, field, model = _describe(loc, root)
    if kind == "extra_forbidden":
        return f"unknown config key '{key}'; allowed: {', '.join(model.model_fields)}"
    if annotation is None:  # a whole section has the wrong type
        return f"config section '{key or 'root'}' must be a mapping, got {value!r}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        return f"config key '{key}' must be {_bounds(annotation, field)}, got {value!r}"
    if kind == "too_short" and typing.get_origin(annotation) is not Literal:
        return f"config key '{key}' must be a non-empty list, got {value!r}"
    if kind == "too_long":
        return f"config key '{key}' must be a list of at most {first['ctx']['max_length']} items, got {len(value)}"
    if kind == "finite_number":
        return f"config key '{key}' must be a finite number, got {value!r}"
    bounds = _bounds(annotation, field)
    members = typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, types.UnionType) else ()
    if bounds and type(None) in members:  # `Positive | None`: "an integer > 0 or null"
        kind_name = _type_name(next(a for a in members if a is not type(None)))
        return f"config key '{key}' must be {kind_name} {bounds} or null, got {value!r}"
    return f"config key '{key}' must be {_type_name(annotation)}{' ' + bounds if bounds else ''}, got {value!r}"
