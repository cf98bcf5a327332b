"""A job file as the body of ``POST /v1/jobs``: the service accepts data only, so a stage's
scene that is a YAML path (relative to the job file) is read here and sent inline; catalogue
names stay names. The service validates everything else (and names any bad field)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gaitforge.service.client.http import ClientError

SCENE_SUFFIXES = (".yaml", ".yml")


def read_job_file(
    path: Path, budget_scale: float = 1.0, overrides: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The job in ``path`` as a JSON-able mapping, as ``gaitforge train`` reads it (its
    ``extends`` followed, ``overrides`` set by dotted path), scene files inlined (composed
    ones as the scene they make) and every stage's env-step budget (and blend ramp)
    multiplied by ``budget_scale`` (as ``gaitforge train --budget-scale`` does).

    Raises:
        ClientError: the file or a scene file cannot be read or is not a YAML mapping, or an
            override does not apply (one line naming the file and the field).
    """
    from gaitforge.learner.job import read_job_fields
    from gaitforge.workers.scenes.compose import compose_file
    from gaitforge.workers.spec_io import SpecError, read_yaml_mapping

    try:
        spec = read_job_fields(path, overrides)
    except SpecError as exc:
        raise ClientError(str(exc)) from None
    stages = spec.get("stages")
    if isinstance(stages, list):
        for i, stage in enumerate(stages):
            if not isinstance(stage, dict):
                continue
            scene = stage.get("scene")
            if isinstance(scene, str) and scene.endswith(SCENE_SUFFIXES):
                where = f"{path}: stages.{i}.scene"
                try:
                    raw = read_yaml_mapping(path.parent / scene)
                    stage["scene"] = compose_file(raw, where).raw
                except SpecError as exc:
                    raise ClientError(f"{where}: {exc}") from None
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
