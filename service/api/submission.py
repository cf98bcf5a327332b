"""Reading a submitted job spec: a JSON or YAML request body -> a mapping; a spec error ->
the 422 problem's ``errors: [{field, message}]``.

The body's shape is bounded as it is parsed, before anything else sees it: mappings and
lists nested deeper than ``max_body_depth`` (YAML: refused while composing; JSON: the
parsed value is measured without recursion) and numbers longer than ``max_number_chars``
(never converted: Python refuses integers of over 4300 digits, and YAML's ``1:2:3...``
integers cost time quadratic in their length) are a 422 naming the field, logged in one line.
"""

from __future__ import annotations

import json
import logging
from typing import Any

import yaml
from gaitforge.service.api.problems import FieldError, ProblemError
from gaitforge.service.jobs.spec import NoAliasLoader
from gaitforge.service.ops import InputError, SpecError

logger = logging.getLogger(__name__)

JSON_TYPES = ("application/json",)
YAML_TYPES = ("application/yaml", "text/yaml", "application/x-yaml", "text/x-yaml")
INVALID_SPEC = "urn:gaitforge:problem:invalid-job-spec"
DEFAULT_MAX_DEPTH = 64
"""as ``ServiceSettings.max_body_depth``'s default"""
DEFAULT_MAX_NUMBER_CHARS = 100
"""as ``ServiceSettings.max_number_chars``'s default"""


class LongNumber:
    """Stands in for a number too long to convert, until its field is named."""

    def __init__(self, text: str) -> None:
        self.chars = len(text)


class TooDeep(yaml.YAMLError):
    """A YAML body nested deeper than its loader's limit."""


class BoundedLoader(NoAliasLoader):
    """YAML without aliases, nested at most ``max_depth`` mappings and lists deep, with
    numbers longer than ``max_number_chars`` left as :class:`LongNumber` (not converted)."""

    def __init__(self, stream: str, max_depth: int, max_number_chars: int) -> None:
        super().__init__(stream)
        self.max_depth = max_depth
        self.max_number_chars = max_number_chars
        self.depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if not self.check_event(yaml.MappingStartEvent, yaml.SequenceStartEvent):
            return super().compose_node(parent, index)
        self.depth += 1
        try:
            if self.depth > self.max_depth:
                line = self.peek_event().start_mark.line + 1
                raise TooDeep(f"nested more than {self.max_depth} levels deep (line {line})")
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def construct_bounded_int(self, node: yaml.ScalarNode) -> Any:
        if len(node.value) > self.max_number_chars:
            return LongNumber(node.value)
        return self.construct_yaml_int(node)

    def construct_bounded_float(self, node: yaml.ScalarNode) -> Any:
        if len(node.value) > self.max_number_chars:
            return LongNumber(node.value)
        return self.construct_yaml_float(node)


BoundedLoader.add_constructor("tag:yaml.org,2002:int", BoundedLoader.construct_bounded_int)
BoundedLoader.add_constructor("tag:yaml.org,2002:float", BoundedLoader.construct_bounded_float)


def spec_problem(field: str, message: str) -> ProblemError:
    """A 422 naming ``field``."""
    errors = [FieldError(field=field, message=message)]
    return ProblemError(422, f"{field}: {message}", type=INVALID_SPEC, errors=errors)


def parse_body(
    body: bytes,
    content_type: str | None,
    max_depth: int = DEFAULT_MAX_DEPTH,
    max_number_chars: int = DEFAULT_MAX_NUMBER_CHARS,
) -> dict[str, Any]:
    """The spec in ``body`` by its media type (JSON when none is given), nested at most
    ``max_depth`` deep, no number longer than ``max_number_chars``.

    Raises:
        ProblemError: 415 for another media type; 422 for text that is not a mapping, is
            nested too deeply or has too long a number.
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
        if media in JSON_TYPES:
            raw = _load_json(text, max_number_chars)
        else:
            raw = _load_yaml(text, max_depth, max_number_chars)
    except json.JSONDecodeError as exc:
        raise spec_problem("body", f"not valid JSON: {exc.msg} (line {exc.lineno})") from None
    except TooDeep as exc:
        raise _refused("body", f"{exc}; at most {max_depth}") from None
    except yaml.YAMLError as exc:
        raise spec_problem("body", f"not valid YAML: {str(exc).splitlines()[0]}") from None
    except RecursionError:
        raise _refused("body", f"nested more than {max_depth} levels deep") from None
    _check_shape(raw, max_depth, max_number_chars)
    if not isinstance(raw, dict):
        raise spec_problem("body", f"expected a mapping of job fields, got {type(raw).__name__}")
    return raw


def _load_json(text: str, max_number_chars: int) -> Any:
    """JSON ``text``, numbers longer than ``max_number_chars`` left as :class:`LongNumber`."""

    def number(convert: Any) -> Any:
        def parse(digits: str) -> Any:
            return LongNumber(digits) if len(digits) > max_number_chars else convert(digits)

        return parse

    return json.loads(text, parse_int=number(int), parse_float=number(float))


def _load_yaml(text: str, max_depth: int, max_number_chars: int) -> Any:
    """YAML ``text`` through :class:`BoundedLoader`."""
    loader = BoundedLoader(text, max_depth, max_number_chars)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def _check_shape(raw: Any, max_depth: int, max_number_chars: int) -> None:
    """``raw`` nests at most ``max_depth`` mappings and lists deep and holds no
    :class:`LongNumber` (walked without recursion).

    Raises:
        ProblemError: 422 naming the field.
    """
    stack: list[tuple[Any, tuple[str, ...], int]] = [(raw, (), 0)]
    while stack:
        value, path, depth = stack.pop()
        field = ".".join(path) or "body"
        if isinstance(value, LongNumber):
            message = f"a number of {value.chars} characters; at most {max_number_chars}"
            raise _refused(field, message)
        if isinstance(value, dict | list):
            if depth + 1 > max_depth:
                raise _refused("body", f"nested more than {max_depth} levels deep")
            pairs = value.items() if isinstance(value, dict) else enumerate(value)
            for key, item in pairs:
                if isinstance(key, LongNumber):
                    raise _refused(field, f"a key of {key.chars} characters (a number)")
                stack.append((item, (*path, str(key)), depth + 1))


def _refused(field: str, message: str) -> ProblemError:
    """A 422 for a body over a parse limit, logged in one line."""
    logger.warning("refused a job body: %s: %s", field, message)
    return spec_problem(field, message)


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
