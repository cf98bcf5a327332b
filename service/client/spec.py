"""A job file as the body of ``POST /v1/jobs``: the service accepts data only, so a stage's
scene that is a YAML path (relative to the job file) is read here and sent inline; catalogue
names stay names. The service validates everything else (and names any bad field)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from gaitforge.service.client.http import ClientError

SCENE_SUFFIXES = (".yaml", ".yml")


def read_job_file(path: Path, budget_scale: float = 1.0) -> dict[str, Any]:
    """The job in ``path`` as a JSON-able mapping, scene files inlined and every stage's
    env-step budget (and blend ramp) multiplied by ``budget_scale`` (as ``gaitforge train
    --budget-scale`` does).

    Raises:
        ClientError: the file or a scene file cannot be read or is not a YAML mapping (one
            line naming the file and the field).
    """
    spec = _read_mapping(path, str(path))
    stages = spec.get("stages")
    if isinstance(stages, list):
        for i, stage in enumerate(stages):
            if not isinstance(stage, dict):
                continue
            scene = stage.get("scene")
            if isinstance(scene, str) and scene.endswith(SCENE_SUFFIXES):
                stage["scene"] = _read_mapping(path.parent / scene, f"{path}: stages.{i}.scene")
            if budget_scale != 1.0:
                scale_stage(stage, budget_scale)
    return spec


def scale_stage(stage: dict[str, Any], scale: float) -> None:
    """Multiply a raw stage's ``env_steps`` and blend ramp by ``scale`` (at least 1), in place;
    the job's default ramp is scaled too. Values the service would reject are left alone."""
    from gaitforge.learner.job import BlendSpec

    steps = stage.get("env_steps")
    if isinstance(steps, int | float) and not isinstance(steps, bool):
        stage["env_steps"] = max(1, round(steps * scale))
    blend = stage.get("blend")
    if blend is None:
        blend = stage["blend"] = {}
    if isinstance(blend, dict):
        ramp = blend.get("ramp_env_steps", BlendSpec().ramp_env_steps)
        if isinstance(ramp, int | float) and not isinstance(ramp, bool):
            blend["ramp_env_steps"] = max(1, round(ramp * scale))


def _read_mapping(path: Path, where: str) -> dict[str, Any]:
    """A YAML file that must hold a mapping."""
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ClientError(f"{where}: cannot read {path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        raise ClientError(f"{where}: {path} is not valid YAML{at}") from None
    if not isinstance(data, dict):
        raise ClientError(f"{where}: {path} must hold a mapping, not {type(data).__name__}")
    return data
