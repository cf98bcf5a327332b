"""Load YAML files into pydantic models with one-line errors that name file and field.

Errors stay short whatever the input: at most :data:`MAX_PROBLEMS` problems are listed (the
rest counted), a bad value or field name is quoted only up to :data:`MAX_ECHO_CHARS`, and a
message is cut at :data:`MAX_MESSAGE_CHARS`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)


MAX_PROBLEMS = 20
"""problems listed of one validation; the others are counted in one more entry"""
MAX_ECHO_CHARS = 80
"""characters of a bad value (its repr) or of a field name quoted back in a problem"""
MAX_MESSAGE_CHARS = 1000
"""characters of one problem's message (a check may quote the value it refuses)"""


class SpecError(ValueError):
    """A user-supplied file is invalid. The message is one line: file, field, what is allowed."""


def shorten(text: str, limit: int = MAX_ECHO_CHARS) -> str:
    """``text``, cut to ``limit`` characters with the length said if it is longer."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def validation_problems(
    err: ValidationError, limit: int | None = MAX_PROBLEMS
) -> list[tuple[str, str]]:
    """Each problem as (dotted field path, what is wrong and what was given): the first
    ``limit`` (None: all), then ``("<root>", "N more problems not listed")`` if there are
    more; field names and given values cut to :data:`MAX_ECHO_CHARS` (a submission of
    unknown keys must not come back as a larger error)."""
    problems = []
    errors = err.errors(include_url=False, include_context=False, include_input=True)
    for e in errors if limit is None else errors[:limit]:
        field = ".".join(shorten(str(p)) for p in e["loc"]) or "<root>"
        msg = shorten(e["msg"].removeprefix("Value error, "), MAX_MESSAGE_CHARS)
        got = e.get("input")
        got_text = (
            "" if isinstance(got, dict | list) or got is None else f" (got {shorten(repr(got))})"
        )
        problems.append((field, f"{msg}{got_text}"))
    if limit is not None and len(errors) > limit:
        problems.append(("<root>", f"{len(errors) - limit} more problems not listed"))
    return problems


def format_validation_error(source: str, err: ValidationError) -> str:
    """One line per problem, each naming ``source`` and the dotted field path."""
    return "; ".join(f"{source}: {field}: {msg}" for field, msg in validation_problems(err))


def read_yaml_mapping(path: Path) -> dict:
    """The mapping in YAML file ``path``.

    Raises:
        SpecError: the file is missing, not YAML, or not a mapping (one line naming it).
    """
    try:
        raw = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise SpecError(f"{path}: file not found") from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{path}: not valid YAML: {str(exc).splitlines()[0]}") from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise SpecError(f"{path}: not valid YAML: {shorten(str(exc), 200)}") from None
    if not isinstance(raw, dict):
        raise SpecError(f"{path}: <root>: expected a mapping of fields, got {type(raw).__name__}")
    return raw


def load_yaml_model(path: Path, model: type[ModelT]) -> ModelT:
    """Read ``path`` as YAML and validate it as ``model``; raise :class:`SpecError` on any fault."""
    return validate_model(read_yaml_mapping(path), model, str(path))


def validate_model(raw: dict, model: type[ModelT], source: str) -> ModelT:
    try:
        return model.model_validate(raw)
    except ValidationError as err:
        raise SpecError(format_validation_error(source, err)) from None
