"""What watches an evaluation episode (observers of ``workers.episode``): the statistics of
each episode, an MCAP recorder, a video writer; and the one-line error type of evaluation."""

from __future__ import annotations

import importlib
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from gaitforge.learner.evaluation.results import EpisodeResult
from gaitforge.workers.episode import EpisodeObserver, EpisodeSummary, Observer
from gaitforge.workers.sim.base import HEALTHY

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv


class EvaluationError(ValueError):
    """Bad evaluation input (path, scene, sizes, options); the message is one line."""


class EpisodeMetrics(Observer):
    """An episode's evaluation statistics: effort (sum of excitation^2 as applied) and each
    weighted reward term summed over the steps; in imitation scenes (``info["imitation"]``
    on every step) the RMS over the steps of the pose error (rad) and whether the bound still
    held on the last step; in obstacle scenes (``env.touching_obstacle()``) the steps that
    ended with a foot on an obstacle and the first one's time (s). :attr:`result` once the
    episode ended."""

    def __init__(self) -> None:
        self.result: EpisodeResult | None = None
        self._effort_sum = 0.0
        self._terms: dict[str, float] = {}
        self._n_muscles = 0
        self._pose_sq, self._pose_steps, self._kept = 0.0, 0, True
        self._touch_steps: int | None = None
        self._first_touch_s: float | None = None

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        self.result, self._effort_sum, self._terms = None, 0.0, {}
        self._n_muscles = int(env.action_space.shape[0])
        self._pose_sq, self._pose_steps, self._kept = 0.0, 0, True
        self._touch_steps = 0 if env.scene.obstacles is not None else None
        self._first_touch_s = None

    def on_step(
        self,
        env: MuscleEnv,
        action: np.ndarray,
        obs: np.ndarray,
        reward: float,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> None:
        self._effort_sum += float(np.sum(action[: self._n_muscles] ** 2))
        for name, value in info.get("reward_terms", {}).items():
            self._terms[name] = self._terms.get(name, 0.0) + float(value)
        imitation = info.get("imitation")
        if imitation is not None:
            error = float(imitation.get("pose_error_rad", math.nan))
            if math.isfinite(error):  # a failed step repeats the last healthy state
                self._pose_sq += error * error
                self._pose_steps += 1
            self._kept = self._kept and bool(imitation.get("kept", False))
        healthy = info.get("health") == HEALTHY
        if self._touch_steps is not None and healthy and env.touching_obstacle():
            self._touch_steps += 1
            if self._first_touch_s is None:
                self._first_touch_s = float(info["step"]) * env.dt

    def on_end(self, summary: EpisodeSummary | None) -> None:
        if summary is not None:
            tracking = None
            if self._pose_steps:
                tracking = (math.sqrt(self._pose_sq / self._pose_steps), self._kept)
            self.result = EpisodeResult.of(
                summary,
                self._effort_sum,
                self._terms,
                self._n_muscles,
                tracking,
                obstacles=None
                if self._touch_steps is None
                else (self._touch_steps, self._first_touch_s),
            )


def check_recording_available(record: bool, video: bool) -> None:
    """Raise :class:`EvaluationError` (one line) if the modules that write recordings or
    videos cannot be imported."""
    wanted = [("--record", "gaitforge.learner.evaluation.recording")] if record else []
    wanted += [("--video", "gaitforge.learner.evaluation.video")] if video else []
    for option, module in wanted:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise EvaluationError(f"{option}: recording not available yet ({exc})") from None


def mcap_observer(path: Path, env: MuscleEnv, metadata: dict[str, str]) -> EpisodeObserver:
    """An MCAP recorder of one episode of ``env`` (``recording.EpisodeRecorder``)."""
    from gaitforge.learner.evaluation.recording import EpisodeRecorder  # lazy: imports foxglove

    return EpisodeRecorder(path, env, metadata)


def video_observer(path: Path, env: MuscleEnv) -> EpisodeObserver:
    """An MP4 of one episode of ``env`` (``video.VideoRecorder``, offscreen, on the CPU).

    Raises:
        EvaluationError: no renderer here, or a scene it cannot render (one line).
    """
    from gaitforge.learner.evaluation.video import VideoRecorder  # lazy: imports the renderer

    try:
        return VideoRecorder(path, env)
    except (RuntimeError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise EvaluationError(f"--video: {first}") from None


def recording_metadata(ckpt: Path, mode: str, seed: int) -> dict[str, str]:
    """Strings for a recording's metadata: the checkpoint's (path, sha256 of its manifest,
    which holds every file's sha256, stage, env steps; ``learner.evaluation.recording``), the action
    mode and the seed."""
    from gaitforge.learner.evaluation.recording import checkpoint_metadata  # lazy: imports foxglove

    return {
        "source": "gaitforge evaluate",
        **checkpoint_metadata(ckpt),
        "mode": mode,
        "seed": str(seed),
    }
