"""Scenes: the spec, the shipped catalogue (bases and options, composed), and pruning.

load_scene("walk-2d")                                   # a base
load_scene("run-2d+clock+one-leg")                      # a base and options
load_scene("run-2d+clock", {"task.target_speed": 2.5})  # and dotted overrides
load_scene("my-scene.yaml")                             # a file (whole, or base: ...)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gaitforge.workers.bodies.reflex_wiring import check_wiring_names, load_wiring
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.overrides import parse_assignments, set_fields
from gaitforge.workers.scenes.compose import (
    SceneOption,
    base_names,
    compose,
    compose_file,
    load_option,
    option_names,
)
from gaitforge.workers.scenes.prune import PrunePlan, check_names, plan_pruning
from gaitforge.workers.scenes.spec import Scene
from gaitforge.workers.spec_io import SpecError, read_yaml_mapping, validate_model

__all__ = [
    "BackendMismatch",
    "PrunePlan",
    "Scene",
    "SceneOption",
    "catalogue",
    "load_option",
    "load_scene",
    "option_names",
    "parse_assignments",
    "plan_pruning",
    "scene_fields",
]


def catalogue() -> list[str]:
    """Names of the shipped base scenes (options compose onto them: :func:`option_names`)."""
    return base_names()


def scene_fields(ref: str) -> dict[str, Any]:
    """The fields of catalogue scene ``ref`` (``base`` or ``base+option+...``) as composed,
    before validation: a starting point for a scene of one's own."""
    return compose(ref).raw


class BackendMismatch(SpecError):
    """A scene asked for on a backend it does not run on; ``backends`` are those it does."""

    def __init__(self, message: str, backends: list[str]) -> None:
        super().__init__(message)
        self.backends = backends


def load_scene(
    name_or_path: str | Path,
    overrides: dict[str, Any] | None = None,
    backend: str | None = None,
) -> Scene:
    """Load a catalogue scene (``base`` or ``base+option+...``) or a scene file by path,
    with ``overrides`` (dotted field path -> value) set last, and check it against its body;
    with ``backend``, on that backend alone (its ``backends`` become ``[backend]``).

    Raises:
        BackendMismatch: ``backend`` is not one of the scene's backends.
        SpecError: one line naming the scene or file, the field and what is allowed.
    """
    path = Path(name_or_path)
    if path.suffix in {".yaml", ".yml"}:
        source = str(path)
        raw = compose_file(read_yaml_mapping(path), source).raw
        if overrides:
            raw = set_fields(raw, overrides, where=source)
    else:
        source = f"scene {str(name_or_path)!r}"
        raw = compose(str(name_or_path), overrides).raw
    if backend is not None:
        backends = raw.get("backends", Scene.model_fields["backends"].default_factory())
        if backend not in backends:
            raise BackendMismatch(f"{source}: runs on {backends}, not on {backend!r}", backends)
        raw = {**raw, "backends": [backend]}
    scene = validate_model(raw, Scene, source)
    try:
        topology = topology_for(scene.body)
        check_names(scene, topology)
    except SpecError as exc:
        raise SpecError(f"{source}: body: {exc}") from None
    except ValueError as exc:
        raise SpecError(f"{source}: {exc}") from None
    if scene.action.gait:
        try:
            wiring = load_wiring(scene.body, scene.action.wiring)
            check_wiring_names(wiring, set(topology.dof_defaults), set(topology.muscles))
        except SpecError as exc:
            raise SpecError(f"{source}: {exc}") from None
    return scene
