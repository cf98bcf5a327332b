"""Examples for the OpenAPI document's schemas that have none of their own: the request (a
job), the scene models and the parts of both, taken from real values (an example job
normalised by its model, catalogue scenes, a compile report) so that they stay valid."""

from __future__ import annotations

from typing import Any


def schema_examples(schemas: dict[str, Any]) -> dict[str, Any]:
    """schema name -> an example, for every schema reachable from the seeds below."""
    from gaitforge.learner.job import Job
    from gaitforge.service.api import routes_scenes
    from gaitforge.service.api.routes_jobs import EXAMPLE_JOB
    from gaitforge.service.api.schemas import ArtifactList, JobStatus
    from gaitforge.workers.scenes import load_scene

    status = JobStatus.model_config["json_schema_extra"]["examples"][0]  # type: ignore[index]
    artifacts = ArtifactList.model_config["json_schema_extra"]["examples"][0]  # type: ignore[index]
    full_job = Job.model_validate(EXAMPLE_JOB).model_dump(mode="json")
    found: dict[str, Any] = {
        "Job": EXAMPLE_JOB,
        "Scene": load_scene("stand-2d").model_dump(mode="json"),
        "WarmStartSpec": {"excitations": "walk", "env_steps": 8192, "rounds": 2},
        "StagePPO": {"lr": 1e-4, "lr_end": 5e-5},
        "StageEvaluation": {"scene": "run-2d+clock", "episodes": 100, "every_env_steps": 250000},
        "StageOptimize": {"population": 16, "generations": 5000, "minutes": 55, "episodes": 2},
        "GaitMeasure": {"min_speed": 1.0, "max_speed": 1.6, "fall": 1.0, "effort": 0.1},
        "Action": status["actions"][0],
        "Artifact": artifacts["items"][0],
        "FieldError": {"field": "stages.0.scene", "message": "unknown scene 'walk-9d'"},
    }
    seeds = [
        ("Job", full_job),
        ("JobStatus", status),
        ("Scene", load_scene("imitate-walk-2d").model_dump(mode="json")),
        ("Scene", load_scene("obstacles-2d").model_dump(mode="json")),
        ("Scene", load_scene("run-2d+clock").model_dump(mode="json")),  # a lead-in
        ("Scene", load_scene("walk-2d+pushes").model_dump(mode="json")),
        ("SceneSummary", routes_scenes.summaries()[0].model_dump(mode="json")),
        ("OptionSummary", routes_scenes.option_summaries()[0].model_dump(mode="json")),
        ("SceneReport", routes_scenes.report("stand-2d", None).model_dump(mode="json")),
    ]
    for name, value in seeds:
        _walk(name, value, schemas, found)
    return found


def _walk(name: str, value: Any, schemas: dict[str, Any], found: dict[str, Any]) -> None:
    """Take ``value`` as an example of schema ``name`` (unless one is known) and walk into
    the properties that refer to other schemas."""
    if not isinstance(value, dict) or name not in schemas:
        return
    found.setdefault(name, value)
    for prop, sub in schemas[name].get("properties", {}).items():
        inner = value.get(prop)
        for item in inner if isinstance(inner, list) else [inner]:
            for ref in _refs(sub):
                _walk(ref, item, schemas, found)


def _refs(schema: Any) -> list[str]:
    """The names of the schemas ``schema`` refers to (through anyOf, oneOf, items)."""
    if not isinstance(schema, dict):
        return []
    out = []
    if "$ref" in schema:
        out.append(schema["$ref"].rsplit("/", 1)[-1])
    for key in ("anyOf", "oneOf", "allOf"):
        for sub in schema.get(key, []):
            out.extend(_refs(sub))
    out.extend(_refs(schema.get("items")))
    return out
