"""The OpenAPI document: FastAPI's, plus the schemas it cannot see (the problem, the job
spec a submission is validated as, an inline scene) and problem+json for every 422."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from gaitforge.learner.job import Job
from gaitforge.service.api.examples import schema_examples
from gaitforge.service.api.problems import PROBLEM_JSON, Problem, problem_responses
from gaitforge.service.jobs.spec import MAX_REF_CHARS
from gaitforge.workers.scenes import Scene, catalogue
from gaitforge.workers.scenes.compose import REF_PATTERN
from pydantic import BaseModel

_REF = "#/components/schemas/{model}"
_FASTAPI_422 = ("HTTPValidationError", "ValidationError")


def _add_model(schemas: dict[str, Any], model: type[BaseModel]) -> None:
    """``model``'s schema and its definitions into ``schemas`` (existing names kept)."""
    schema = model.model_json_schema(ref_template=_REF)
    for name, definition in schema.pop("$defs", {}).items():
        schemas.setdefault(name, definition)
    schemas.setdefault(model.__name__, schema)


def build_openapi(app: FastAPI) -> dict[str, Any]:
    """``app``'s OpenAPI document (built once)."""
    if app.openapi_schema:
        return app.openapi_schema
    doc = get_openapi(
        title=app.title,
        version=app.version,
        description=app.description,
        routes=app.routes,
        tags=app.openapi_tags,
    )
    schemas = doc.setdefault("components", {}).setdefault("schemas", {})
    for model in (Problem, Job, Scene):
        _add_model(schemas, model)
    stage = schemas["Stage"]["properties"]
    stage["scene"] = {
        "anyOf": [
            {
                "type": "string",
                "pattern": REF_PATTERN.pattern,
                "maxLength": MAX_REF_CHARS,
                "description": f"a catalogue scene: a base ({', '.join(catalogue())}) or "
                "base+option+... (GET /v1/scenes/options)",
            },
            {"$ref": "#/components/schemas/Scene"},
        ],
        "description": "a catalogue scene (base or base+option+...), or an inline scene (the "
        "scene file's fields); never a path",
    }
    rule = {
        "anyOf": [
            {
                "type": "string",
                "description": "'<metric> >=|<= <value> [over <episodes>]' on training episodes, "
                "or 'eval.<metric> >=|<= <value>' on the stage's evaluation",
            },
            {"$ref": "#/components/schemas/PromotionRule"},
        ]
    }
    stage["promote"] = {
        "anyOf": [rule, {"type": "array", "items": rule}],
        "description": "rules that must all pass to promote early; one rule may be given alone",
    }
    problem_422 = problem_responses(422)[422]
    for operations in doc.get("paths", {}).values():
        for operation in operations.values():
            responses = operation.get("responses", {})
            content = responses.get("422", {}).get("content", {})
            if "application/json" in content and PROBLEM_JSON not in content:
                responses["422"] = problem_422
    for name in _FASTAPI_422:
        schemas.pop(name, None)
    for name, example in schema_examples(schemas).items():
        if name in schemas and not schemas[name].get("examples"):
            schemas[name]["examples"] = [example]
    app.openapi_schema = doc
    return doc
