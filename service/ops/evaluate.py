"""Evaluation operations: a checkpoint's distance, speed, falls, effort and health (on imitation
scenes also the tracking error, rad, and the share of episodes that kept the gait) over seeded
episodes, and the speed-against-safety sweep (the work is ``learner.evaluation.evaluate``'s)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from gaitforge.service.ops.errors import InputError
from gaitforge.workers.spec_types import Seed
from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    from gaitforge.learner.evaluation.evaluate import EvaluationReport

Mode = Literal["deterministic", "stochastic"]
ProgressFn = Callable[[str, int, int], None]
"""``(label, episodes done, episodes in total)`` after each episode"""


class EvaluateRequest(BaseModel):
    """What to evaluate and how (see ``learner.evaluation.evaluate.evaluate_checkpoint``)."""

    model_config = ConfigDict(extra="forbid")

    checkpoint: Path = Field(description="a checkpoint directory, or a run directory")
    scene: str | None = Field(
        default=None,
        description="evaluate on this scene (name or YAML) instead of the "
        "checkpoint's; its observation and action sizes must match the policy's",
    )
    backend: Literal["mujoco", "opensim"] | None = Field(
        default=None, description="simulator (default: the checkpoint's)"
    )
    episodes: int = Field(default=10, description="episodes per mode and per sweep point")
    modes: list[Mode] = Field(default=["deterministic"], description="action modes")
    seed: Seed = Field(default=0, description="episode i resets with seed + i")
    scene_set: dict[str, Any] = Field(
        default_factory=dict,
        description="scene fields set by dotted path (``task.target_speed``), on ``scene`` "
        "or on the checkpoint's own",
    )
    sweep: list[float] | None = Field(
        default=None,
        description="target-speed reductions, fractions in [0, 1), for the "
        "speed-against-safety sweep (in the first mode); None: no sweep",
    )
    pick: Literal["latest", "best"] = Field(
        default="latest", description="from a run directory: the latest or the best (return)"
    )
    record: Path | None = Field(default=None, description="MCAP file of the first episode")
    video: Path | None = Field(default=None, description="MP4 file of the first episode")
    gait: Path | None = Field(
        default=None,
        description="PNG of the first episode's joint angles over the gait cycle beside the "
        "recorded gait; its stride, cadence, symmetry and clearance go into the report",
    )


def parse_percentages(text: str, field: str = "sweep_percent") -> list[float]:
    """ "0,10,20,30" (percent) -> [0.0, 0.1, 0.2, 0.3].

    Raises:
        InputError: not comma-separated numbers, or one outside [0, 100).
    """
    try:
        values = [float(part) / 100.0 for part in text.split(",") if part.strip()]
    except ValueError:
        raise InputError(field, f"{text!r}: expected comma-separated percentages") from None
    if not values or any(not 0.0 <= v < 1.0 for v in values):
        raise InputError(field, f"{text!r}: each must be in [0, 100)")
    return values


def evaluate(request: EvaluateRequest, progress: ProgressFn | None = None) -> EvaluationReport:
    """Evaluate ``request.checkpoint``; the report serialises with ``report.to_dict()``
    (:func:`report_json`).

    Raises:
        EvaluationError: bad path, scene, backend, sizes or options (one line).
        CheckpointError: a damaged checkpoint (naming the file).
    """
    from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint  # lazy: torch, MuJoCo

    return evaluate_checkpoint(
        request.checkpoint,
        scene=request.scene,
        scene_set=request.scene_set,
        backend=request.backend,
        episodes=request.episodes,
        modes=request.modes,
        seed=request.seed,
        sweep=request.sweep,
        sweep_mode=request.modes[0] if request.modes else "deterministic",
        record=request.record,
        video=request.video,
        gait=request.gait,
        pick=request.pick,
        progress=progress,
    )


def report_json(report: EvaluationReport) -> dict[str, Any]:
    """The report as JSON-able data (NaN as null, ``return_`` as ``"return"``)."""
    return report.to_dict()


def write_report(report: EvaluationReport, path: Path) -> None:
    """Write :func:`report_json` to ``path`` (indented JSON; its folder is made)."""
    from gaitforge.learner.evaluation.evaluate import write_json

    write_json(report, path)


def user_errors() -> tuple[type[Exception], ...]:
    """The exceptions :func:`evaluate` raises for bad input, each with a one-line message."""
    from gaitforge.learner.checkpoint import CheckpointError  # lazy: imports torch
    from gaitforge.learner.evaluation.evaluate import EvaluationError

    return (EvaluationError, CheckpointError, InputError)
