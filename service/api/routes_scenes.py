"""``/v1/scenes``: the scene catalogue and a scene's compile report
(:mod:`gaitforge.service.ops.scenes`). Only catalogue names are looked up, never paths. A
catalogue scene asked for on a backend it does not run on (``elbow-reach`` on OpenSim) is a
409 naming the backends it runs on: the query is valid, the scene cannot be built there."""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal

from fastapi import APIRouter, Depends, Path, Query
from gaitforge.service.api.auth import require_owner
from gaitforge.service.api.problems import PROBLEM_JSON, ProblemError, problem_responses
from gaitforge.service.ops import InputError, SpecError
from gaitforge.service.ops import scenes as ops

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


BACKEND_NOT_SUPPORTED = "urn:gaitforge:problem:backend-not-supported"
_NOT_ON_BACKEND = {
    "description": "the scene does not run on that backend (the detail names those it runs on)",
    "content": {
        PROBLEM_JSON: {
            "schema": {"$ref": "#/components/schemas/Problem"},
            "example": {
                "type": BACKEND_NOT_SUPPORTED,
                "title": "Conflict",
                "status": 409,
                "detail": "scene 'elbow-reach' runs on mujoco only, not on opensim",
                "instance": "/v1/scenes/elbow-reach",
            },
        }
    },
}


def not_on_backend(name: str, backends: list[str], backend: str) -> ProblemError:
    """The 409 for catalogue scene ``name`` asked for on a ``backend`` it does not run on."""
    runs = f"{backends[0]} only" if len(backends) == 1 else " and ".join(backends)
    detail = f"scene {name!r} runs on {runs}, not on {backend}"
    return ProblemError(409, detail, type=BACKEND_NOT_SUPPORTED)


@router.get(
    "/{name}",
    response_model=ops.SceneReport,
    summary="A scene's compile report",
    responses={**problem_responses(404, 422), 409: _NOT_ON_BACKEND},
)
def show_scene(
    name: Annotated[str, Path(max_length=100, description="a catalogue scene's name")],
    backend: Annotated[
        Literal["mujoco", "opensim"] | None,
        Query(description="simulator to compile for (default: the scene's first)"),
    ] = None,
) -> ops.SceneReport:
    """Compile the scene and report what it kept, what it dropped and what that saved; a
    backend the scene does not run on is a 409 naming those it runs on (the catalogue lists
    each scene's backends)."""
    listed = {s.name: s for s in summaries()}
    if name not in listed:
        raise ProblemError(404, f"no scene {name!r} in the catalogue")
    if backend is not None and backend not in listed[name].backends:
        raise not_on_backend(name, listed[name].backends, backend)
    try:
        return report(name, backend)
    except InputError as exc:  # (checked above; the scene itself says so too)
        raise ProblemError(409, str(exc), type=BACKEND_NOT_SUPPORTED) from None
    except SpecError as exc:
        raise ProblemError(404, str(exc)) from None
