"""``/v1/scenes``: the scene catalogue and a scene's compile report
(:mod:`gaitforge.service.ops.scenes`). Only catalogue names are looked up, never paths."""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal

from fastapi import APIRouter, Depends, Path, Query
from gaitforge.service.api.auth import require_owner
from gaitforge.service.api.problems import FieldError, ProblemError, problem_responses
from gaitforge.service.ops import InputError, SpecError
from gaitforge.service.ops import scenes as ops
from gaitforge.workers.scenes import catalogue

router = APIRouter(
    prefix="/v1/scenes",
    tags=["scenes"],
    dependencies=[Depends(require_owner)],
    responses=problem_responses(401),
)


@lru_cache(maxsize=1)
def summaries() -> tuple[ops.SceneSummary, ...]:
    """The catalogue's scenes (listed once per process: the catalogue ships with the code)."""
    return tuple(ops.list_scenes())


@lru_cache(maxsize=64)
def report(name: str, backend: str | None) -> ops.SceneReport:
    """Scene ``name``'s compile report for ``backend`` (compiled once per process)."""
    return ops.show_scene(name, backend)


@router.get("", response_model=list[ops.SceneSummary], summary="The scene catalogue")
def list_scenes() -> list[ops.SceneSummary]:
    """Every shipped scene: body, backends, task, control rate, episode length."""
    return list(summaries())


@router.get(
    "/{name}",
    response_model=ops.SceneReport,
    summary="A scene's compile report",
    responses=problem_responses(404, 422),
)
def show_scene(
    name: Annotated[str, Path(max_length=100, description="a catalogue scene's name")],
    backend: Annotated[
        Literal["mujoco", "opensim"] | None,
        Query(description="simulator to compile for (default: the scene's first)"),
    ] = None,
) -> ops.SceneReport:
    """Compile the scene and report what it kept, what it dropped and what that saved."""
    if name not in catalogue():
        raise ProblemError(404, f"no scene {name!r} in the catalogue")
    try:
        return report(name, backend)
    except InputError as exc:  # the scene does not run on that backend
        errors = [FieldError(field=exc.field, message=exc.problem)]
        raise ProblemError(422, str(exc), errors=errors) from None
    except SpecError as exc:
        raise ProblemError(404, str(exc)) from None
