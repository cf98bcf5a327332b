"""Load YAML files into pydantic models with one-line errors that name file and field."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)


class SpecError(ValueError):
    """A user-supplied file is invalid. The message is one line: file, field, what is allowed."""


def validation_problems(err: ValidationError) -> list[tuple[str, str]]:
    """Each problem as (dotted field path, what is wrong and what was given)."""
    problems = []
    for e in err.errors():
        field = ".".join(str(p) for p in e["loc"]) or "<root>"
        msg = e["msg"].removeprefix("Value error, ")
        got = e.get("input")
        got_text = "" if isinstance(got, dict | list) or got is None else f" (got {got!r})"
        problems.append((field, f"{msg}{got_text}"))
    return problems


def format_validation_error(source: str, err: ValidationError) -> str:
    """One line per problem, each naming ``source`` and the dotted field path."""
    return "; ".join(f"{source}: {field}: {msg}" for field, msg in validation_problems(err))


def load_yaml_model(path: Path, model: type[ModelT]) -> ModelT:
    """Read ``path`` as YAML and validate it as ``model``; raise :class:`SpecError` on any fault."""
    try:
        raw = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise SpecError(f"{path}: file not found") from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{path}: not valid YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(raw, dict):
        raise SpecError(f"{path}: <root>: expected a mapping of fields, got {type(raw).__name__}")
    return validate_model(raw, model, str(path))


def validate_model(raw: dict, model: type[ModelT], source: str) -> ModelT:
    try:
        return model.model_validate(raw)
    except ValidationError as err:
        raise SpecError(format_validation_error(source, err)) from None
