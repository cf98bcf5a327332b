"""A job's progress as its trainer process reports it: ``progress.json`` (the newest state,
replaced atomically, at least once per iteration) and ``metrics.jsonl`` (one JSON object
per iteration, appended). The entry writes them; the runner and the API read them.
"""

from __future__ import annotations

import json
import logging
import math
import os
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

logger = logging.getLogger(__name__)

Phase = Literal["starting", "training", "evaluating", "finished", "stopped", "failed"]
FINAL_PHASES: frozenset[str] = frozenset({"finished", "stopped", "failed"})
"""phases after which the trainer process exits"""


class RuleProgress(BaseModel):
    """A promotion rule of the current stage against the episodes so far."""

    rule: str = Field(description="the rule, e.g. 'survival >= 0.95 over 100 episodes'")
    metric: str = Field(description="return, distance (m), speed (m/s), fall_rate, ...")
    op: Literal[">=", "<="]
    target: float = Field(description="the value the window mean must reach")
    window: int = Field(description="episodes the mean is over")
    episodes: int = Field(description="episodes finished in the stage so far (up to window)")
    value: float | None = Field(description="the mean over the last window episodes (None: none)")
    passing: bool = Field(description="the mean passes and the window is full")


class StageProgress(BaseModel):
    """The curriculum stage being trained."""

    index: int = Field(description="0-based stage index")
    name: str
    scene: str
    count: int = Field(description="stages in the job")
    env_steps: int = Field(description="env steps done in this stage")
    budget_env_steps: int = Field(description="the stage's env-step budget")
    promote: list[RuleProgress] = Field(default_factory=list)


class JobProgress(BaseModel):
    """Where a job's trainer process stands (``progress.json``)."""

    model_config = ConfigDict(extra="ignore")

    phase: Phase
    pid: int = Field(description="the trainer process")
    host: str = Field(description="the machine it runs on")
    updated_at: datetime = Field(description="when written (UTC)")
    iteration: int = Field(default=0, description="PPO updates of the run so far")
    env_steps: int = Field(default=0, description="env steps of the run so far")
    steps_per_s: float | None = Field(default=None, description="env steps/s, last iteration")
    stage: StageProgress | None = None
    metrics: dict[str, Any] = Field(
        default_factory=dict,
        description="the last iteration's metrics: return, distance (m), speed (m/s), "
        "fall_rate, survival, length (s) over the last 100 episodes; reward_terms (mean per "
        "env step), health (counts in the batch), lr, losses, ...",
    )
    checkpoint: str | None = Field(default=None, description="the newest checkpoint's name")
    error: str | None = Field(default=None, description="why it failed (one line)")
    traceback: str | None = None


def now() -> datetime:
    return datetime.now(UTC)


def jsonable(value: Any) -> Any:
    """``value`` with non-finite floats as None and numpy scalars as Python numbers
    (mappings and sequences walked; anything else unknown becomes its ``str``)."""
    if isinstance(value, bool) or value is None or isinstance(value, str | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if hasattr(value, "item"):  # numpy scalar
        return jsonable(value.item())
    return str(value)


def write_progress(path: Path, progress: JobProgress) -> None:
    """Replace ``path`` with ``progress`` atomically (a reader sees the old or the new)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(progress.model_dump_json())
    os.replace(tmp, path)


def read_progress(path: Path) -> JobProgress | None:
    """The progress in ``path``; None if there is none yet or it does not read."""
    try:
        return JobProgress.model_validate_json(path.read_bytes())
    except FileNotFoundError:
        return None
    except (OSError, ValidationError) as exc:
        logger.warning("%s: unreadable progress (%s)", path, str(exc).splitlines()[0])
        return None


def append_metrics(path: Path, metrics: dict[str, Any]) -> None:
    """Append one iteration's metrics to ``path`` as a JSON line (non-finite -> null)."""
    line = json.dumps(jsonable(metrics), allow_nan=False, separators=(",", ":"))
    with path.open("a") as f:
        f.write(line + "\n")


def read_metrics(path: Path, start: int = 0, limit: int | None = None) -> list[dict[str, Any]]:
    """Iterations ``start`` .. ``start + limit - 1`` (0-based lines) of ``path``; a last line
    still being written (no newline yet, or not JSON) is left out."""
    rows: list[dict[str, Any]] = []
    try:
        with path.open() as f:
            for index, line in enumerate(f):
                if index < start or not line.endswith("\n"):
                    continue
                if limit is not None and len(rows) >= limit:
                    break
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError:
                    logger.warning("%s: line %d is not JSON; skipped", path, index + 1)
    except FileNotFoundError:
        return []
    return rows


def trim_metrics(path: Path, last_iteration: int) -> int:
    """Drop the lines of iterations after ``last_iteration`` (a resumed run goes on from its
    checkpoint's iteration: the lines a stopped attempt wrote after it would repeat), and a
    torn last line; returns the lines kept. Rewritten atomically, only if something goes."""
    try:
        lines = path.read_text().splitlines(keepends=True)
    except FileNotFoundError:
        return 0
    kept = []
    for line in lines:
        try:
            row = json.loads(line) if line.endswith("\n") else None
        except json.JSONDecodeError:
            row = None
        if isinstance(row, dict) and int(row.get("iteration", 0)) <= last_iteration:
            kept.append(line)
    if len(kept) != len(lines):
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text("".join(kept))
        os.replace(tmp, path)
    return len(kept)
