"""Evaluation results: one episode, N episodes in one action mode with their 95 % intervals,
the speed-against-safety sweep's points, and a checkpoint's report; JSON out.

Units: distance m (pelvis forward displacement, end minus start), speed m/s (distance over
episode time), turned deg (the pelvis's turn about the vertical, end against start,
counter-clockwise seen from above; over N episodes the mean of its size: a 3-D walker that
turns loses distance, and this says why; 0 on a planar body), time s (control steps /
control_hz), effort 1 (mean over steps and muscles of excitation^2, the excitation as
applied, clipped to [0, 1]), effort_sum (sum of excitation^2 over steps and muscles), return
(sum of the scene's weighted reward terms).

Imitation scenes (``task.imitate``; the env reports ``info["imitation"]`` every step) add the
tracking error, rad: per episode the RMS over its steps of the step's pose error (itself the
RMS over the tracked kept joints), so ``sqrt(mean_t err_t^2)``; and whether the episode *kept
the gait*: its pose error never passed the scene's bound (``kept`` on its last step), it did
not fall, the simulator stayed healthy and it ran to the episode's end (``episode_s``). Over
N episodes: the tracking error's mean with its t interval and the kept share with its Wilson
interval. Other scenes leave these fields None (JSON ``null``): the keys are always there.

Obstacle scenes (the evaluation asks ``MuscleEnv.touching_obstacle()`` after every healthy
step) add per episode the steps that ended with a foot touching an obstacle sphere and the
first one's time, and over N episodes the share that touched one and the fall rate among
those that did and those that did not (Wilson intervals; NaN where a group is empty): how
much of the fall rate the obstacles cause. Other scenes leave these None.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from gaitforge.learner.evaluation.gait_quality import GaitQuality
from gaitforge.learner.evaluation.stats import Rate, Stat
from gaitforge.workers.episode import EpisodeSummary
from gaitforge.workers.scenes import Scene

Mode = Literal["deterministic", "stochastic"]
MODES: tuple[Mode, ...] = ("deterministic", "stochastic")


@dataclass(frozen=True)
class EpisodeResult:
    """One episode.

    Attributes:
        seed: the env's reset seed.
        steps: control steps taken.
        time_s: simulated time, s (steps / control_hz).
        distance_m: pelvis forward displacement, end minus start, m.
        mean_speed_m_s: distance_m / time_s, m/s.
        turned_deg: the pelvis's turn about the vertical, end against start, deg
            (counter-clockwise seen from above).
        fell: ended by a fall (pelvis below the scene's ``min_pelvis_height``).
        health: the health cause the episode ended with ("ok" unless the simulator failed).
        truncated: reached the episode's length (``episode_s``).
        return_: sum of the weighted reward terms.
        effort: mean over steps and muscles of excitation^2 (1).
        effort_sum: sum over steps and muscles of excitation^2 (1).
        reward_terms: each weighted term summed over the episode.
        tracking_error_rad: imitation scenes: RMS over the steps of the pose error (rad,
            itself RMS over the tracked kept joints); None elsewhere.
        kept_gait: imitation scenes: the pose error stayed within the bound, no fall, no
            simulator failure, and the episode ran to its end; None elsewhere.
        obstacle_contact_steps: obstacle scenes: control steps that ended with a foot
            touching an obstacle sphere; None elsewhere.
        first_obstacle_touch_s: obstacle scenes: s from the start to the first such step;
            None if there was none or the scene has no obstacles.
    """

    seed: int
    steps: int
    time_s: float
    distance_m: float
    mean_speed_m_s: float
    turned_deg: float
    fell: bool
    health: str
    truncated: bool
    return_: float
    effort: float
    effort_sum: float
    reward_terms: dict[str, float]
    tracking_error_rad: float | None = None
    kept_gait: bool | None = None
    obstacle_contact_steps: int | None = None
    first_obstacle_touch_s: float | None = None

    @property
    def touched_obstacle(self) -> bool:
        """A foot touched an obstacle sphere in this episode."""
        return bool(self.obstacle_contact_steps)

    @classmethod
    def of(
        cls,
        summary: EpisodeSummary,
        effort_sum: float,
        reward_terms: dict[str, float],
        n_muscles: int,
        tracking: tuple[float, bool] | None = None,
        obstacles: tuple[int, float | None] | None = None,
    ) -> EpisodeResult:
        """From the loop's summary, the episode's sum of excitation^2 and each weighted term's
        sum; ``n_muscles`` is the action's size; ``tracking`` (imitation scenes): the
        episode's RMS pose error (rad) and whether the bound held on its last step;
        ``obstacles`` (obstacle scenes): the steps that ended touching an obstacle and the
        first one's time (s, None if none)."""
        steps, time_s, distance = summary.steps, summary.time_s, summary.distance_m
        ran_out = summary.truncated and not summary.fell and summary.health == "ok"
        return cls(
            seed=summary.seed,
            steps=steps,
            time_s=time_s,
            distance_m=distance,
            mean_speed_m_s=distance / time_s if time_s > 0 else 0.0,
            turned_deg=math.degrees(summary.turned_rad),
            fell=summary.fell,
            health=summary.health,
            truncated=ran_out,
            return_=summary.return_,
            effort=effort_sum / (steps * max(1, n_muscles)) if steps else 0.0,
            effort_sum=effort_sum,
            reward_terms=reward_terms,
            tracking_error_rad=None if tracking is None else float(tracking[0]),
            kept_gait=None if tracking is None else bool(tracking[1] and ran_out),
            obstacle_contact_steps=None if obstacles is None else int(obstacles[0]),
            first_obstacle_touch_s=None if obstacles is None else obstacles[1],
        )


@dataclass(frozen=True)
class ModeResult:
    """N episodes in one action mode at one target speed, and their aggregates (see
    :class:`EpisodeResult` for units)."""

    mode: Mode
    scene: str
    backend: str
    target_speed_m_s: float | None
    episodes: list[EpisodeResult]
    distance_m: Stat
    mean_speed_m_s: Stat
    turned_deg: Stat
    """the size of the episodes' turns, deg"""
    time_s: Stat
    steps: Stat
    return_: Stat
    effort: Stat
    effort_sum: Stat
    fall_rate: Rate
    failure_rate: Rate
    """episodes ended by a simulator failure (health other than "ok")"""
    survival_rate: Rate
    """episodes that ran to their end (``episode_s``) without a fall or a simulator failure:
    the ``survival`` of a promotion rule"""
    health: dict[str, int]
    """episodes by the health cause they ended with ("ok" included)"""
    tracking_error_rad: Stat | None = None
    """imitation scenes: the episodes' RMS pose error, rad (None elsewhere)"""
    kept_gait_rate: Rate | None = None
    """imitation scenes: the share of episodes that kept the gait to their end (None elsewhere)"""
    touched_rate: Rate | None = None
    """obstacle scenes: the share of episodes in which a foot touched an obstacle sphere
    (None elsewhere)"""
    fall_rate_touched: Rate | None = None
    """obstacle scenes: falls among the episodes that touched an obstacle (None elsewhere)"""
    fall_rate_untouched: Rate | None = None
    """obstacle scenes: falls among the episodes that touched none (None elsewhere)"""

    @property
    def turned(self) -> bool:
        """Some episode's pelvis turned about the vertical (a planar body's never does)."""
        return any(e.turned_deg != 0.0 for e in self.episodes)

    @classmethod
    def of(
        cls,
        mode: Mode,
        scene: Scene,
        backend: str,
        episodes: list[EpisodeResult],
    ) -> ModeResult:
        n = len(episodes)

        def stat(name: str) -> Stat:
            return Stat.of([float(getattr(e, name)) for e in episodes])

        imitating = [e for e in episodes if e.tracking_error_rad is not None]
        tracking = kept = None
        if imitating:
            tracking = Stat.of([float(e.tracking_error_rad or 0.0) for e in imitating])
            kept = Rate.of(sum(bool(e.kept_gait) for e in imitating), len(imitating))
        among_obstacles = [e for e in episodes if e.obstacle_contact_steps is not None]
        touched_rate = fall_touched = fall_untouched = None
        if among_obstacles:
            touched = [e for e in among_obstacles if e.touched_obstacle]
            untouched = [e for e in among_obstacles if not e.touched_obstacle]
            touched_rate = Rate.of(len(touched), len(among_obstacles))
            fall_touched = Rate.of(sum(e.fell for e in touched), len(touched))
            fall_untouched = Rate.of(sum(e.fell for e in untouched), len(untouched))

        return cls(
            mode=mode,
            scene=scene.name,
            backend=backend,
            target_speed_m_s=scene.task.target_speed,
            episodes=episodes,
            distance_m=stat("distance_m"),
            mean_speed_m_s=stat("mean_speed_m_s"),
            turned_deg=Stat.of([abs(e.turned_deg) for e in episodes]),
            time_s=stat("time_s"),
            steps=stat("steps"),
            return_=stat("return_"),
            effort=stat("effort"),
            effort_sum=stat("effort_sum"),
            fall_rate=Rate.of(sum(e.fell for e in episodes), n),
            failure_rate=Rate.of(sum(e.health != "ok" for e in episodes), n),
            survival_rate=Rate.of(sum(e.truncated for e in episodes), n),
            health=dict(sorted(Counter(e.health for e in episodes).items())),
            tracking_error_rad=tracking,
            kept_gait_rate=kept,
            touched_rate=touched_rate,
            fall_rate_touched=fall_touched,
            fall_rate_untouched=fall_untouched,
        )


@dataclass(frozen=True)
class SweepPoint:
    """The evaluation at target speed ``(1 - reduction) * nominal`` (m/s)."""

    reduction: float
    target_speed_m_s: float
    result: ModeResult


@dataclass(frozen=True)
class EvaluationReport:
    """A checkpoint's evaluation: one :class:`ModeResult` per mode at the scene's own target
    speed and, if asked, the speed-against-safety sweep (in ``sweep_mode``)."""

    checkpoint: str | None
    env_steps: int | None
    scene: str
    backend: str
    seed: int
    results: dict[str, ModeResult]
    sweep: list[SweepPoint] = field(default_factory=list)
    sweep_mode: Mode | None = None
    stage: dict | None = None
    notes: list[str] = field(default_factory=list)
    """what the figures do not say (e.g. a policy trained at one pace asked for another)"""
    recording: str | None = None
    """MCAP file of the first episode, if one was written"""
    video: str | None = None
    """MP4 file of the first episode, if one was written"""
    gait: GaitQuality | None = None
    """the first episode's gait beside the recorded one, if asked"""
    gait_plot: str | None = None
    """PNG of its joint angles over the gait cycle, if one was written"""

    def to_dict(self) -> dict[str, Any]:
        """JSON-able: NaN written as null, the field ``return_`` as ``"return"``."""
        return _finite(asdict(self))


def _finite(x: Any) -> Any:
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {("return" if k == "return_" else k): _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    return x


def write_json(report: EvaluationReport, path: Path) -> None:
    """Write ``report.to_dict()`` to ``path`` (indented JSON)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report.to_dict(), indent=2) + "\n")
