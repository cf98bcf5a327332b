"""``gaitforge ship CKPT DEST``: copy a trained checkpoint into the repository as a shipped
policy (``learner.evaluation.ship``: no optimizer state, a provenance in its meta.json)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from gaitforge.learner.checkpoint import CheckpointError
from gaitforge.learner.evaluation.ship import ship_policy
from gaitforge.service.console import fail, out


def ship(
    checkpoint: Annotated[Path, typer.Argument(help="The checkpoint directory to ship.")],
    dest: Annotated[Path, typer.Argument(help="Where: e.g. examples/policies/walk-2d.")],
    command: Annotated[str, typer.Option(help="The command that trained it.")],
    commit: Annotated[
        str | None, typer.Option(help="The commit it was trained at; default: its record.")
    ] = None,
    evaluation: Annotated[
        Path | None, typer.Option(help="Its evaluation (gaitforge evaluate --json) to cite.")
    ] = None,
) -> None:
    """Ship a checkpoint as a policy in the repository (gaitforge evaluate it, or start a
    job from it with init_from)."""
    report = None
    if evaluation is not None:
        try:
            report = json.loads(evaluation.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise fail(f"--evaluation: {evaluation}: {exc}") from None
    try:
        written = ship_policy(checkpoint, dest, command, commit, report)
    except CheckpointError as exc:
        raise fail(exc) from None
    out.print(f"shipped {checkpoint} to {written}")
