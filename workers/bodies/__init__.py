"""Neutral (simulator-independent) body descriptions and the catalogue of shipped bodies."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.spec_io import SpecError, load_yaml_model

__all__ = ["Body", "available_bodies", "load_body"]


def _data_dir() -> Path:
    return Path(str(resources.files("gaitforge.workers.bodies") / "data"))


def available_bodies() -> list[str]:
    """Names of the neutral bodies shipped with the package."""
    return sorted(p.stem for p in _data_dir().glob("*.yaml"))


@lru_cache(maxsize=16)
def load_body(name_or_path: str) -> Body:
    """Load a shipped body by name, or any body file by path."""
    path = Path(name_or_path)
    if path.suffix not in {".yaml", ".yml"}:
        path = _data_dir() / f"{name_or_path}.yaml"
        if not path.exists():
            raise SpecError(
                f"body {name_or_path!r}: unknown; shipped bodies are {available_bodies()}"
            )
    return load_yaml_model(path, Body)
