"""Neutral (simulator-independent) body descriptions and the catalogue of shipped bodies."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

import yaml
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.spec_io import SpecError, load_yaml_model

__all__ = ["Body", "available_bodies", "body_yaml", "load_body"]


def _data_dir() -> Path:
    return Path(str(resources.files("gaitforge.workers.bodies") / "data"))


def available_bodies() -> list[str]:
    """Names of the neutral bodies shipped with the package."""
    return sorted(p.stem for p in _data_dir().glob("*.yaml"))


@lru_cache(maxsize=16)
def load_body(name_or_path: str) -> Body:
    """Load a shipped body by name, any body file by path, or an OpenSim model (``.osim``:
    imported as ``gaitforge bodies import`` does, which also writes its report)."""
    path = Path(name_or_path)
    if path.suffix == ".osim":
        from gaitforge.workers.bodies.osim_import import import_osim

        return import_osim(path).body
    if path.suffix not in {".yaml", ".yml"}:
        path = _data_dir() / f"{name_or_path}.yaml"
        if not path.exists():
            raise SpecError(
                f"body {name_or_path!r}: unknown; shipped bodies are {available_bodies()}"
            )
    return load_yaml_model(path, Body)


def body_yaml(body: Body, header: str = "") -> str:
    """``body`` as a body file (``load_body`` reads it back equal), fields at their
    defaults left out; ``header`` lines become comments at the top."""
    data = body.model_dump(mode="json", exclude_defaults=True)
    comments = "".join(f"# {line}\n" for line in header.splitlines())
    return comments + yaml.dump(data, Dumper=_BodyDumper, sort_keys=False, width=100)


class _BodyDumper(yaml.SafeDumper):
    """Lists of numbers on one line (``[0.1, 0.0, 0.2]``), everything else in block style."""


def _represent_list(dumper: yaml.SafeDumper, items: list) -> yaml.Node:
    flat = all(isinstance(i, int | float | str) for i in items)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", items, flow_style=flat)


_BodyDumper.add_representer(list, _represent_list)
