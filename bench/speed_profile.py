"""Where a policy's speed goes within an episode: the pelvis's forward speed against time
from the reset, per time bin, over deterministic episodes of a scene (the median and the
10th-90th percentiles over the episodes still up in that bin), the target speed the reward
asks for there (a clock's, with ``speed_target_from_clock``), and where the falls come; in a
scene whose policy paces its clock (``clock_rate_span``), the clock's rate per bin too.

Usage: python bench/speed_profile.py CHECKPOINT [CHECKPOINT ...] [--scene run-2d+clock]
           [--episodes 30] [--seed 0] [--bin-s 0.4] [--labels A B ...] [--out profile.png]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from gaitforge.learner.checkpoint import CheckpointError, load_policy
from gaitforge.learner.eval_observers import EvaluationError
from gaitforge.learner.evaluate import fitted_to_scene, resolve_checkpoint
from gaitforge.learner.evaluate_episodes import make_runner, policy_act
from gaitforge.workers.episode import Observer
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError
from rich.console import Console
from rich.table import Table

matplotlib.use("Agg")
import matplotlib.pyplot as plt

console = Console(width=160)


class DistanceLog(Observer):
    """The pelvis's forward distance from the reset (m) after each step, the target speed
    (m/s, None without one) the step was rewarded against, the imitation clock's rate in the
    step (1 without one), and whether the episode fell."""

    def on_reset(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> None:
        self.distance, self.target, self.rate, self.fell = [0.0], [], [], False

    def on_step(self, env: Any, action: np.ndarray, obs: np.ndarray, reward: float,
                terminated: bool, truncated: bool, info: dict[str, Any]) -> None:  # fmt: skip
        self.distance.append(float(info["distance"]))
        self.target.append(env.target_speed())
        self.rate.append(float(info.get("imitation", {}).get("clock_rate", 1.0)))
        self.fell = self.fell or terminated


@dataclass
class Profile:
    """Per bin (``bin_s`` seconds): speeds [episodes up in the bin] (m/s), the clock's mean
    rate in the bin [episodes up in it], the target (m/s or nan) and the falls that came in
    it."""

    bin_s: float
    speeds: list[list[float]] = field(default_factory=list)
    rates: list[list[float]] = field(default_factory=list)
    target: list[float] = field(default_factory=list)
    falls: list[int] = field(default_factory=list)
    episodes: int = 0

    @property
    def paced(self) -> bool:
        """The clock's rate moved from 1 in some bin (the policy paces it)."""
        return any(r != 1.0 for rates in self.rates for r in rates)


def profile(checkpoint: Path, scene_ref: str, episodes: int, seed: int, bin_s: float) -> Profile:
    policy, meta = load_policy(resolve_checkpoint(checkpoint))
    scene = load_scene(scene_ref).resolved()
    # a runner on the obstacles it never saw, or on a clock it never paced (kept at its rate)
    policy, _ = fitted_to_scene(policy, meta.obs_names, scene, "mujoco")
    per_bin = max(1, round(bin_s * scene.control_hz))
    bins = scene.steps_per_episode // per_bin
    out = Profile(bin_s=per_bin / scene.control_hz, speeds=[[] for _ in range(bins)],
                  rates=[[] for _ in range(bins)], target=[float("nan")] * bins,
                  falls=[0] * bins, episodes=episodes)  # fmt: skip
    with make_runner(policy, scene, "mujoco") as runner:
        for i in range(episodes):
            log = DistanceLog()
            runner.run(policy_act(policy, "deterministic", seed + i), seed + i, [log])
            steps = len(log.distance) - 1
            for b in range(min(bins, steps // per_bin)):
                ahead = log.distance[(b + 1) * per_bin] - log.distance[b * per_bin]
                out.speeds[b].append(ahead / out.bin_s)
                out.rates[b].append(float(np.mean(log.rate[b * per_bin : (b + 1) * per_bin])))
                target = log.target[(b + 1) * per_bin - 1]
                out.target[b] = float("nan") if target is None else target
            if log.fell:
                out.falls[min(bins - 1, (steps - 1) // per_bin)] += 1
    return out


def table(labels: list[str], profiles: list[Profile]) -> Table:
    result = Table(title="pelvis forward speed (m/s) from the reset: median (p10-p90); falls")
    result.add_column("until s", justify="right")
    result.add_column("target", justify="right")
    for label in labels:
        result.add_column(label, justify="right")
    first = profiles[0]
    for b in range(len(first.speeds)):
        cells = []
        for p in profiles:
            v = np.array(p.speeds[b])
            cell = (
                "-"
                if v.size == 0
                else (f"{np.median(v):.2f} ({np.percentile(v, 10):.2f}-{np.percentile(v, 90):.2f})")
            )
            if p.paced and v.size:
                cell += f"; rate {np.median(p.rates[b]):.2f}"
            cells.append(cell + (f"; {p.falls[b]} fell" if p.falls[b] else ""))
        result.add_row(f"{(b + 1) * first.bin_s:.1f}", f"{first.target[b]:.2f}", *cells)
    return result


def plot(labels: list[str], profiles: list[Profile], scene: str, out: Path) -> None:
    paced = any(p.paced for p in profiles)
    fig, axes = plt.subplots(2 if paced else 1, 1, figsize=(8, 7 if paced else 4.5), sharex=True,
                             squeeze=False, height_ratios=[2, 1] if paced else None)  # fmt: skip
    ax = axes[0, 0]
    for label, p in zip(labels, profiles, strict=True):
        t = (np.arange(len(p.speeds)) + 0.5) * p.bin_s
        up = [np.array(s) if s else np.array([np.nan]) for s in p.speeds]
        median = [np.median(v) for v in up]
        ax.plot(t, median, marker=".", label=f"{label} ({sum(p.falls)}/{p.episodes} fell)")
        ax.fill_between(t, [np.percentile(v, 10) for v in up], [np.percentile(v, 90) for v in up],
                        alpha=0.2)  # fmt: skip
    t = (np.arange(len(profiles[0].target)) + 0.5) * profiles[0].bin_s
    ax.plot(t, profiles[0].target, "k--", label="target speed")
    ax.set_ylabel("pelvis forward speed (m/s)")
    ax.set_title(f"{scene}: deterministic episodes, median and 10-90 %")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if paced:
        ax = axes[1, 0]
        for label, p in zip(labels, profiles, strict=True):
            t = (np.arange(len(p.rates)) + 0.5) * p.bin_s
            ax.plot(t, [np.median(r) if r else np.nan for r in p.rates], marker=".", label=label)
        ax.set_ylabel("clock rate (median)")
        ax.grid(alpha=0.3)
    ax.set_xlabel("time from standing (s)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", type=Path, nargs="+")
    parser.add_argument("--scene", default="run-2d+clock")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bin-s", type=float, default=0.4, help="s; whole control steps")
    parser.add_argument("--labels", nargs="+")
    parser.add_argument("--out", type=Path, help="a PNG (and the figures as JSON beside it)")
    args = parser.parse_args()
    labels = args.labels or [c.name for c in args.checkpoints]
    if len(labels) != len(args.checkpoints):
        raise SystemExit(f"--labels: {len(labels)} for {len(args.checkpoints)} checkpoints")
    profiles = []
    for checkpoint in args.checkpoints:
        console.log(f"{checkpoint}: {args.episodes} episodes of {args.scene}")
        try:
            profiles.append(profile(checkpoint, args.scene, args.episodes, args.seed, args.bin_s))
        except (EvaluationError, CheckpointError, SpecError) as exc:
            raise SystemExit(str(exc)) from None
    console.print(table(labels, profiles))
    if args.out is not None:
        plot(labels, profiles, Path(args.scene).stem, args.out)  # a file: its name
        args.out.with_suffix(".json").write_text(json.dumps(
            {"scene": args.scene, "seed": args.seed,
             "profiles": {label: p.__dict__ for label, p in zip(labels, profiles, strict=True)}},
            indent=1))  # fmt: skip
        console.log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
