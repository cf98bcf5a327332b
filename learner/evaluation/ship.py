"""Shipping a trained policy with the repository: a checkpoint copied to a folder of its own
(``examples/policies/<scene>/``) as the trainer writes one, without the optimizer's state
(the policy and normaliser safetensors are a few hundred kB) or the episodes its curriculum
kept for promotion rules (tens of kB of one run's history), its ``meta.json`` given a
``provenance``: the command and seed that made it, the commit it was trained at, the
checkpoint it was copied from and, if given, its evaluation's headline figures.

A shipped policy is evaluated like any checkpoint (``gaitforge evaluate
examples/policies/walk-2d``) and starts a job's first stage with ``init_from:``.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from gaitforge.learner.checkpoint import load_checkpoint, save_checkpoint

logger = logging.getLogger(__name__)


def headline(report: dict[str, Any]) -> dict[str, Any]:
    """The figures of an evaluation report (``gaitforge evaluate --json``'s
    ``results.deterministic``, or that mapping itself) that a shipped policy names."""
    result = report.get("results", {}).get("deterministic", report)
    keep = ("mean_speed_m_s", "fall_rate", "time_s", "tracking_error_rad", "kept_gait_rate")
    out: dict[str, Any] = {"scene": result.get("scene"), "backend": result.get("backend")}
    for key in keep:
        value = result.get(key)
        if isinstance(value, dict):
            out[key] = value.get("mean", value.get("value"))
            out["episodes"] = value.get("n", out.get("episodes"))
    return out


def ship_policy(
    source: Path,
    dest: Path,
    command: str,
    commit: str | None = None,
    evaluation: dict[str, Any] | None = None,
) -> Path:
    """Copy checkpoint ``source`` to ``dest`` (replaced if it exists) with its provenance.

    Args:
        source: a checkpoint directory.
        dest: the shipped policy's directory (e.g. ``examples/policies/walk-2d``).
        command: the command that trained it.
        commit: the commit it was trained at; default: the one its checkpoint recorded.
        evaluation: an evaluation report (see :func:`headline`).

    Raises:
        CheckpointError: ``source`` is not a whole checkpoint.
    """
    state, meta = load_checkpoint(source)
    job = meta.job or {}
    provenance = {
        "command": command,
        "seed": job.get("seed"),
        "job": job.get("name"),
        "commit": commit or meta.versions.get("gaitforge_commit", "unknown"),
        "trained_env_steps": meta.env_steps,
        "copied_from": str(source),
    }
    if evaluation is not None:
        provenance["evaluation"] = headline(evaluation)
    curriculum = meta.curriculum
    if curriculum is not None:  # the promotion window's episodes: a run's, not the policy's
        curriculum = curriculum.model_copy(update={"episodes": []})
    shipped = meta.model_copy(
        update={"provenance": provenance, "optimizer_param_groups": None, "curriculum": curriculum}
    )
    with tempfile.TemporaryDirectory(dir=dest.parent if dest.parent.exists() else None) as tmp:
        written = save_checkpoint(Path(tmp), meta.env_steps, state, shipped, keep_last=1)
        if dest.exists():
            shutil.rmtree(dest)
        dest.parent.mkdir(parents=True, exist_ok=True)
        written.rename(dest)
    _readable_as_umask_allows(dest)
    logger.info("shipped %s to %s: %s", source, dest, json.dumps(provenance))
    return dest


def _readable_as_umask_allows(folder: Path) -> None:
    """Give ``folder`` (made in a private temporary directory) and its files the modes a new
    folder and file get here (0o777 and 0o666 less the umask): a shipped policy is for
    anyone who checks out the repository."""
    umask = os.umask(0)
    os.umask(umask)
    folder.chmod(0o777 & ~umask)
    for path in folder.iterdir():
        path.chmod(0o666 & ~umask)
