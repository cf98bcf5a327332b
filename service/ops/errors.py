"""Typed errors of the operations layer: every message is one line.

Operations raise :class:`~gaitforge.workers.spec_io.SpecError` (a bad scene or job file:
the message names the file and the field) or :class:`InputError` (a bad argument: it names
the argument). Evaluation raises ``EvaluationError`` and ``CheckpointError`` as
``learner.evaluation.evaluate`` does. A caller shows ``str(exc)``; the CLI shows an ``InputError``'s
field as its option (``--tolerance``), the REST service as the request field.
"""

from __future__ import annotations

from typing import TypeVar

from gaitforge.workers.spec_io import SpecError, shorten
from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)


class InputError(SpecError):
    """A bad argument of an operation.

    Attributes:
        field: the argument's name (``tolerance``, ``backend``), as in the request model.
        problem: what is wrong with it and what is allowed (one line).
    """

    def __init__(self, field: str, problem: str) -> None:
        super().__init__(f"{field}: {problem}")
        self.field = field
        self.problem = problem


def validate_request(model: type[ModelT], **values: object) -> ModelT:
    """``model(**values)``, a validation failure raised as :class:`InputError` naming the
    first bad field."""
    try:
        return model(**values)
    except ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"]) or "request"
        got = first.get("input")
        got_text = (
            "" if isinstance(got, dict | list) or got is None else f", got {shorten(repr(got))}"
        )
        raise InputError(field, first["msg"].removeprefix("Value error, ") + got_text) from None
