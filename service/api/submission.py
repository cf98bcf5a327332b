"""Reading a submitted job spec: a JSON or YAML request body -> a mapping; a spec error ->
the 422 problem's ``errors: [{field, message}]``."""

from __future__ import annotations

import json
from typing import Any

import yaml
from gaitforge.service.api.problems import FieldError, ProblemError
from gaitforge.service.jobs.spec import NoAliasLoader
from gaitforge.service.ops import InputError, SpecError

JSON_TYPES = ("application/json",)
YAML_TYPES = ("application/yaml", "text/yaml", "application/x-yaml", "text/x-yaml")
INVALID_SPEC = "urn:gaitforge:problem:invalid-job-spec"


def spec_problem(field: str, message: str) -> ProblemError:
    """A 422 naming ``field``."""
    errors = [FieldError(field=field, message=message)]
    return ProblemError(422, f"{field}: {message}", type=INVALID_SPEC, errors=errors)


def parse_body(body: bytes, content_type: str | None) -> dict[str, Any]:
    """The spec in ``body`` by its media type (JSON when none is given).

    Raises:
        ProblemError: 415 for another media type; 422 for text that is not a mapping.
    """
    media = (content_type or "application/json").split(";", 1)[0].strip().lower()
    if media not in JSON_TYPES + YAML_TYPES:
        allowed = ", ".join(JSON_TYPES + YAML_TYPES[:2])
        raise ProblemError(415, f"Content-Type {media!r} is not accepted; send one of {allowed}")
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise spec_problem("body", f"not UTF-8 text (byte {exc.start})") from None
    try:
        raw = json.loads(text) if media in JSON_TYPES else yaml.load(text, NoAliasLoader)
    except json.JSONDecodeError as exc:
        raise spec_problem("body", f"not valid JSON: {exc.msg} (line {exc.lineno})") from None
    except yaml.YAMLError as exc:
        raise spec_problem("body", f"not valid YAML: {str(exc).splitlines()[0]}") from None
    except RecursionError:
        raise spec_problem("body", "nested too deeply") from None
    if not isinstance(raw, dict):
        raise spec_problem("body", f"expected a mapping of job fields, got {type(raw).__name__}")
    return raw


def field_errors(exc: SpecError, source: str = "job") -> list[FieldError]:
    """The fields a spec error names: ``"job: stages.0.scene: unknown"; ...`` -> each
    ``{field: stages.0.scene, message: unknown}``."""
    if isinstance(exc, InputError):
        return [FieldError(field=exc.field, message=exc.problem)]
    listed = getattr(exc, "errors", None)  # SubmissionError: [(field, problem), ...]
    if isinstance(listed, list) and listed:
        return [FieldError(field=_field(f), message=str(m)) for f, m in listed]
    parts: list[str] = []
    for part in str(exc).split("; "):
        if part.startswith(f"{source}: ") or not parts:
            parts.append(part.removeprefix(f"{source}: "))
        else:
            parts[-1] += "; " + part
    out = []
    for part in parts:
        field, sep, message = part.partition(": ")
        if not sep or " " in field:
            field, message = "body", part
        out.append(FieldError(field=_field(field), message=message))
    return out


def _field(field: object) -> str:
    """A spec error's field as the API names it (the whole spec: ``body``)."""
    text = str(field)
    return "body" if text in ("<root>", "") else text


def invalid_spec(exc: SpecError) -> ProblemError:
    """The 422 problem for a spec error."""
    errors = field_errors(exc)
    detail = "; ".join(f"{e.field}: {e.message}" for e in errors)
    return ProblemError(422, detail, type=INVALID_SPEC, errors=errors)
