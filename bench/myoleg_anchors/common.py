"""What both anchor runners share: the run folder, the training clock and the progress CSV.

A run folder ``DIR`` holds ``run.json`` (what was run: runner, seed, settings, versions),
``state.json`` (where training stands: training seconds, env steps, newest checkpoint),
``progress.csv`` and, at the end, ``eval.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import os
import platform
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

ENV_ID = "myoLegWalk-v0"
RUN_FILE = "run.json"
STATE_FILE = "state.json"
PROGRESS_FILE = "progress.csv"
EVAL_FILE = "eval.json"
PROGRESS_COLUMNS = ("wall_s", "env_steps", "episodes", "mean_return", "mean_length")
#: Seconds of training between two progress rows.
PROGRESS_INTERVAL_S = 30.0
#: Seconds of training between two checkpoints.
CHECKPOINT_INTERVAL_S = 600.0


def machine_cores() -> int:
    """CPU cores this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def package_versions(*names: str) -> dict[str, str]:
    """Installed versions of the named distributions ("absent" where not installed)."""
    versions = {"python": platform.python_version()}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "absent"
    return versions


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` to ``path`` atomically (a crash leaves the old file or the new one)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=str) + "\n")
    tmp.replace(path)


def read_json(path: Path) -> dict[str, Any]:
    """The JSON object in ``path``."""
    return json.loads(path.read_text())


def prepare_run_dir(out: Path, resume: bool, run_info: dict[str, Any]) -> dict[str, Any]:
    """Create or reopen the run folder; return the saved training state (empty if fresh).

    Args:
        out: the run folder.
        resume: continue the run in ``out`` rather than start one.
        run_info: what this run is (written to ``run.json`` on a fresh start).

    Raises:
        SystemExit: a fresh start in a folder that already holds a run, or a resume of
            another runner's run.
    """
    out.mkdir(parents=True, exist_ok=True)
    run_path = out / RUN_FILE
    if not resume:
        if run_path.exists():
            raise SystemExit(f"{out} already holds a run: pass --resume or use another --out")
        write_json(run_path, run_info)
        return {}
    if not run_path.exists():
        raise SystemExit(f"--resume: no run in {out} ({RUN_FILE} missing)")
    saved = read_json(run_path)
    if saved.get("runner") != run_info["runner"]:
        raise SystemExit(f"--resume: {out} is a {saved.get('runner')} run")
    state_path = out / STATE_FILE
    return read_json(state_path) if state_path.exists() else {}


class TrainClock:
    """Training seconds, summed over restarts, with pauses (checkpoint writes) left out.

    Args:
        budget_s: training seconds the whole run may use, s.
        already_s: training seconds earlier restarts used, s.
    """

    def __init__(self, budget_s: float, already_s: float = 0.0) -> None:
        self.budget_s = float(budget_s)
        self.already_s = float(already_s)
        self._start = time.monotonic()
        self._paused_s = 0.0

    def start(self) -> None:
        """Start counting this process's training time now."""
        self._start = time.monotonic()
        self._paused_s = 0.0

    def elapsed(self) -> float:
        """Training seconds of the whole run so far, s."""
        return self.already_s + time.monotonic() - self._start - self._paused_s

    def remaining(self) -> float:
        """Training seconds left in the budget, s (may be negative)."""
        return self.budget_s - self.elapsed()

    def expired(self) -> bool:
        """Whether the budget is spent."""
        return self.remaining() <= 0.0

    @contextmanager
    def paused(self) -> Iterator[None]:
        """Leave the time spent inside the ``with`` block out of the training time."""
        t0 = time.monotonic()
        try:
            yield
        finally:
            self._paused_s += time.monotonic() - t0


@dataclass
class ProgressLog:
    """Appends rows of (training s, env steps, episodes, mean return, mean length) to a CSV.

    Each row covers the episodes that ended since the previous row; ``mean_return`` is the
    sum of MyoSuite's reward over an episode, ``mean_length`` its steps (one step = 0.01 s).
    Rows without finished episodes have empty means.

    Args:
        path: the CSV file (appended to; the header is written when the file is new).
        interval_s: training seconds between rows, s.
    """

    path: Path
    interval_s: float = PROGRESS_INTERVAL_S
    _returns: list[float] = field(default_factory=list)
    _lengths: list[int] = field(default_factory=list)
    _last_row_s: float | None = None

    def __post_init__(self) -> None:
        if not self.path.exists():
            with self.path.open("w", newline="") as f:
                csv.writer(f).writerow(PROGRESS_COLUMNS)

    def episode(self, episode_return: float, length: int) -> None:
        """Record one finished episode: its return (1) and its length (steps)."""
        self._returns.append(float(episode_return))
        self._lengths.append(int(length))

    def maybe_write(self, wall_s: float, env_steps: int, force: bool = False) -> None:
        """Write a row if ``interval_s`` has passed since the last one (or ``force``).

        Args:
            wall_s: training seconds of the run so far, s.
            env_steps: env steps of the run so far (all envs together).
            force: write now.
        """
        if self._last_row_s is None:
            self._last_row_s = wall_s
        if not force and wall_s - self._last_row_s < self.interval_s:
            return
        n = len(self._returns)
        mean_r = f"{sum(self._returns) / n:.4f}" if n else ""
        mean_l = f"{sum(self._lengths) / n:.2f}" if n else ""
        with self.path.open("a", newline="") as f:
            csv.writer(f).writerow([f"{wall_s:.1f}", env_steps, n, mean_r, mean_l])
        log.info(
            "progress: %.0f s, %d steps, %d episodes, mean return %s, mean length %s",
            wall_s,
            env_steps,
            n,
            mean_r or "-",
            mean_l or "-",
        )
        self._returns.clear()
        self._lengths.clear()
        self._last_row_s = wall_s


def setup_logging() -> None:
    """INFO-level logging to stderr with timestamps (for the runner scripts)."""
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )


def run_arguments(doc: str) -> argparse.ArgumentParser:
    """The options both runners take (a runner adds its own): ``--minutes`` (training time
    of the run, min), ``--seed``, ``--out``, ``--resume``, ``--checkpoint-minutes``,
    ``--eval-episodes``, ``--eval-seed``, ``--torch-threads``."""
    p = argparse.ArgumentParser(description=doc.split("\n", 1)[0])
    p.add_argument("--minutes", type=float, required=True, help="training time of the run")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument(
        "--checkpoint-minutes",
        type=float,
        default=CHECKPOINT_INTERVAL_S / 60.0,
        help="training minutes between checkpoints",
    )
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument("--torch-threads", type=int, default=1, help="threads of the learner process")
    p.add_argument("--eval-seed", type=int, default=1000)
    return p
