"""``/v1/scenes``: the scene catalogue (base scenes and the options that compose onto them)
and a scene's compile report (:mod:`gaitforge.service.ops.scenes`). Only catalogue
references (``base`` or ``base+option+...``) are looked up, never paths; ``set`` query
parameters set fields by dotted path as ``--set`` does. A scene asked for on a backend it
does not run on (``elbow-reach`` on OpenSim) is a 409 naming the backends it runs on: the
query is valid, the scene cannot be built there."""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal

from fastapi import APIRouter, Depends, Path, Query
from gaitforge.service.api.auth import require_owner
from gaitforge.service.api.problems import PROBLEM_JSON, ProblemError, problem_responses
from gaitforge.service.jobs.spec import MAX_REF_CHARS
from gaitforge.service.ops import InputError, SpecError
from gaitforge.service.ops import scenes as ops
from gaitforge.workers.overrides import parse_assignments
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.compose import is_reference
from pydantic import StringConstraints

MAX_SETS = 32
"""the most ``set`` query parameters of one request"""
MAX_SET_CHARS = 300
"""the longest ``set`` query parameter"""

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


@lru_cache(maxsize=1)
def option_summaries() -> tuple[ops.OptionSummary, ...]:
    """The catalogue's options (listed once per process)."""
    return tuple(ops.list_options())


@lru_cache(maxsize=64)
def report(name: str, backend: str | None, assignments: tuple[str, ...] = ()) -> ops.SceneReport:
    """Scene ``name``'s compile report for ``backend`` with ``assignments`` (``PATH=VALUE``;
    compiled once per process)."""
    return ops.show_scene(name, backend, parse_assignments(list(assignments), where="set"))


@router.get("", response_model=list[ops.SceneSummary], summary="The base scenes")
def list_scenes() -> list[ops.SceneSummary]:
    """Every shipped base scene: body, backends, task, control rate, episode length."""
    return list(summaries())


@router.get("/options", response_model=list[ops.OptionSummary], summary="The scene options")
def list_options() -> list[ops.OptionSummary]:
    """Every shipped option: the bases it composes onto (``base+option+...``), the options
    it must follow, and what it changes."""
    return list(option_summaries())


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
    name: Annotated[
        str,
        Path(
            max_length=MAX_REF_CHARS,
            description="a catalogue scene: a base, or base+option+... (e.g. run-2d+clock)",
        ),
    ],
    backend: Annotated[
        Literal["mujoco", "opensim"] | None,
        Query(description="simulator to compile for (default: the scene's first)"),
    ] = None,
    set_fields: Annotated[
        list[Annotated[str, StringConstraints(max_length=MAX_SET_CHARS)]] | None,
        Query(
            alias="set",
            max_length=MAX_SETS,
            description="a field set by dotted path, PATH=VALUE with the value as YAML "
            "(e.g. task.target_speed=2.5); repeat for more",
        ),
    ] = None,
) -> ops.SceneReport:
    """Compile the scene and report what it kept, what it dropped and what that saved; a
    backend the scene does not run on is a 409 naming those it runs on (the catalogue lists
    each scene's backends)."""
    if not is_reference(name):
        raise ProblemError(404, f"no scene {name!r} in the catalogue")
    try:
        scene = load_scene(name)
    except SpecError as exc:
        raise ProblemError(404, str(exc)) from None
    if backend is not None and backend not in scene.backends:
        raise not_on_backend(name, list(scene.backends), backend)
    try:
        return report(name, backend, tuple(set_fields or ()))
    except InputError as exc:  # (checked above; the scene itself says so too)
        raise ProblemError(409, str(exc), type=BACKEND_NOT_SUPPORTED) from None
    except SpecError as exc:
        raise ProblemError(422, str(exc)) from None
