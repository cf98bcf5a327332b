"""A film strip (PNG) of one deterministic episode of a checkpoint: frames at chosen times,
side by side, with the reference skeleton in imitation scenes. For READMEs, where an MP4
does not play; ``gaitforge evaluate CKPT --video`` makes the whole episode's MP4.

Usage: python bench/film_strip.py CKPT --out strip.png [--times 0 1 2 3 4 5] [--seed 0]
       [--scene NAME] [--backend mujoco]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "osmesa")

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluation.episodes import make_runner, policy_act
from gaitforge.learner.evaluation.evaluate import resolve_checkpoint
from gaitforge.learner.evaluation.video import VideoRecorder
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.episode import Observer
from gaitforge.workers.scenes import load_scene


class Frames(Observer):
    """Keeps the rendered frame of each step whose time (s) is in ``times``."""

    def __init__(self, video: VideoRecorder, times: list[float], control_hz: float) -> None:
        self.video = video
        self.steps = {round(t * control_hz): t for t in times}
        self.frames: list[tuple[float, np.ndarray]] = []
        self._step = 0

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        self._step = 0
        self._keep(env)

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
        self._step += 1
        self._keep(env)

    def _keep(self, env: MuscleEnv) -> None:
        if self._step in self.steps:
            self.frames.append((self.steps[self._step], self.video.render(env)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--times", type=float, nargs="+", default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scene", help="evaluate on this scene instead of the checkpoint's")
    parser.add_argument("--backend", default=None)
    args = parser.parse_args()
    path = resolve_checkpoint(args.checkpoint)
    policy, meta = load_policy(path)
    scene = load_scene(args.scene).resolved() if args.scene else meta.scene_spec()
    runner = make_runner(policy, scene, args.backend or meta.backend, meta.obs_names)
    # the recorder renders; no frame is captured, so it writes no MP4
    with VideoRecorder(args.out.with_suffix(".mp4"), runner.env, 360, 360) as video:
        frames = Frames(video, args.times, scene.control_hz)
        summary = runner.run(policy_act(policy, "deterministic", args.seed), args.seed, [frames])
    fig, axes = plt.subplots(1, len(frames.frames), figsize=(2.2 * len(frames.frames), 2.6))
    for ax, (t, image) in zip(np.atleast_1d(axes), frames.frames, strict=True):
        ax.imshow(image)
        ax.set_title(f"{t:g} s", fontsize=9)
        ax.axis("off")
    fig.suptitle(
        f"{scene.name}: {path.name}, seed {args.seed}; the episode lasted "
        f"{summary.steps / scene.control_hz:.1f} s, {summary.distance_m:.1f} m",
        fontsize=9,
    )
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
