"""What watches an evaluation episode: an MCAP recorder, a video writer, or several at once;
and the one-line error type of evaluation."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv


class EvaluationError(ValueError):
    """Bad evaluation input (path, scene, sizes, options); the message is one line."""


class EpisodeObserver(Protocol):
    """Sees every step of one episode (a recorder or a video writer); ``action`` is the
    excitation applied, clipped to [0, 1]."""

    def on_reset(self, env: Any, obs: np.ndarray) -> None: ...

    def on_step(
        self, env: Any, action: np.ndarray, obs: np.ndarray, reward: float, info: dict
    ) -> None: ...

    def close(self) -> None: ...


class McapObserver:
    """Records one episode to an MCAP file with ``learner.recording.EpisodeRecorder``."""

    def __init__(self, path: Path, env: MuscleEnv, metadata: dict[str, str]) -> None:
        from gaitforge.learner.recording import EpisodeRecorder  # lazy: imports foxglove

        self.recorder = EpisodeRecorder(path, env, metadata)

    def on_reset(self, env: MuscleEnv, obs: np.ndarray) -> None:
        pass

    def on_step(
        self, env: MuscleEnv, action: np.ndarray, obs: np.ndarray, reward: float, info: dict
    ) -> None:
        self.recorder.log_step(env, action, info.get("reward_terms"), info)

    def close(self) -> None:
        self.recorder.close()


def check_recording_available(record: bool, video: bool) -> None:
    """Raise :class:`EvaluationError` (one line) if the modules that write recordings or
    videos cannot be imported."""
    wanted = [("--record", "gaitforge.learner.recording")] if record else []
    wanted += [("--video", "gaitforge.learner.video")] if video else []
    for option, module in wanted:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise EvaluationError(f"{option}: recording not available yet ({exc})") from None


class VideoObserver:
    """Renders one episode to an MP4 with ``learner.video.VideoRecorder`` (offscreen, CPU)."""

    def __init__(self, path: Path, env: MuscleEnv) -> None:
        from gaitforge.learner.video import VideoRecorder  # lazy: imports the renderer

        try:
            self.video = VideoRecorder(path, env)
        except (RuntimeError, ValueError) as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise EvaluationError(f"--video: {first}") from None

    def on_reset(self, env: MuscleEnv, obs: np.ndarray) -> None:
        self.video.capture(env)

    def on_step(
        self, env: MuscleEnv, action: np.ndarray, obs: np.ndarray, reward: float, info: dict
    ) -> None:
        self.video.capture(env)

    def close(self) -> None:
        self.video.close()


def recording_metadata(ckpt: Path, mode: str, seed: int) -> dict[str, str]:
    """Strings for a recording's metadata: the checkpoint's (path, sha256 of its manifest,
    which holds every file's sha256, stage, env steps; ``learner.recording``), the action
    mode and the seed."""
    from gaitforge.learner.recording import checkpoint_metadata  # lazy: imports foxglove

    return {"source": "gaitforge evaluate", **checkpoint_metadata(ckpt), "mode": mode,
            "seed": str(seed)}  # fmt: skip


class Fanout:
    """Several observers as one; each is closed even if another fails."""

    def __init__(self, observers: list[EpisodeObserver]) -> None:
        self.observers = observers

    def on_reset(self, env: Any, obs: np.ndarray) -> None:
        for o in self.observers:
            o.on_reset(env, obs)

    def on_step(
        self, env: Any, action: np.ndarray, obs: np.ndarray, reward: float, info: dict
    ) -> None:
        for o in self.observers:
            o.on_step(env, action, obs, reward, info)

    def close(self) -> None:
        errors = []
        for o in self.observers:
            try:
                o.close()
            except Exception as exc:  # close the others, then raise the first
                errors.append(exc)
        if errors:
            raise errors[0]
