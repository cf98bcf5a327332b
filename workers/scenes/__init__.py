"""Scenes: the spec, the shipped catalogue, and pruning."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.scenes.prune import PrunePlan, check_names, plan_pruning
from gaitforge.workers.scenes.spec import Scene
from gaitforge.workers.spec_io import SpecError, load_yaml_model

__all__ = ["PrunePlan", "Scene", "catalogue", "catalogue_file", "load_scene", "plan_pruning"]


def _catalogue_dir() -> Path:
    return Path(str(resources.files("gaitforge.workers.scenes") / "catalogue"))


def catalogue_file(name: str) -> Path:
    """Path of a shipped scene's YAML file."""
    return _catalogue_dir() / f"{name}.yaml"


def catalogue() -> list[str]:
    """Names of the shipped scenes."""
    return sorted(p.stem for p in _catalogue_dir().glob("*.yaml"))


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a catalogue scene by name, or a scene file by path, and check it against its body.

    Raises:
        SpecError: one line naming the file, the field and what is allowed.
    """
    path = Path(name_or_path)
    if path.suffix not in {".yaml", ".yml"}:
        path = catalogue_file(str(name_or_path))
        if not path.exists():
            raise SpecError(f"scene {str(name_or_path)!r}: unknown; catalogue: {catalogue()}")
    scene = load_yaml_model(path, Scene)
    try:
        check_names(scene, topology_for(scene.body))
    except SpecError as exc:
        raise SpecError(f"{path}: body: {exc}") from None
    except ValueError as exc:
        raise SpecError(f"{path}: {exc}") from None
    return scene
