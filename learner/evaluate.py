"""Evaluation: run a checkpoint's policy on its scene (or another with the same sizes) for N
episodes with fixed seeds and report distance, speed, falls, effort, return and health.

Two action modes: ``deterministic`` (the policy's mean excitation) and ``stochastic`` (a
sample from its Gaussian, drawn from a generator seeded per episode, so a stochastic
evaluation repeats exactly too). Episode ``i`` resets the env with seed ``seed + i`` in every
mode and at every sweep point: the modes and speeds are compared on the same initial states.

The *speed-against-safety sweep* lowers the scene's target speed (m/s) by fractions (0, 10,
20, 30 % by default) and evaluates at each: the target speed is in the observation, so the
same policy is asked to go slower, and the fall rate at each speed says what speed buys.

Everything runs in-process on one env (no Ray). Results are dataclasses; ``to_dict()`` gives
JSON-able dicts and :func:`write_json` a file.

Units: distance m (pelvis forward displacement, end minus start), speed m/s (distance over
episode time), time s (control steps / control_hz), effort 1 (mean over steps and muscles of
excitation^2, the excitation as applied, clipped to [0, 1]), effort_sum (sum of excitation^2
over steps and muscles), return (sum of the scene's weighted reward terms).
"""

from __future__ import annotations

import json
import logging
import math
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import torch
from gaitforge.learner.checkpoint import (
    CheckpointError,
    checkpoints,
    latest_checkpoint,
    load_policy,
)
from gaitforge.learner.eval_observers import (
    EpisodeObserver,
    EvaluationError,
    Fanout,
    McapObserver,
    VideoObserver,
    check_recording_available,
    recording_metadata,
)
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.stats import Rate, Stat
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv

logger = logging.getLogger(__name__)

Mode = Literal["deterministic", "stochastic"]
MODES: tuple[Mode, ...] = ("deterministic", "stochastic")
DEFAULT_REDUCTIONS: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3)
"""fractions by which the sweep lowers the target speed"""


# ---- results --------------------------------------------------------------------------------


@dataclass(frozen=True)
class EpisodeResult:
    """One episode.

    Attributes:
        seed: the env's reset seed.
        steps: control steps taken.
        time_s: simulated time, s (steps / control_hz).
        distance_m: pelvis forward displacement, end minus start, m.
        mean_speed_m_s: distance_m / time_s, m/s.
        fell: ended by a fall (pelvis below the scene's ``min_pelvis_height``).
        health: the health cause the episode ended with ("ok" unless the simulator failed).
        truncated: reached the episode's length (``episode_s``).
        return_: sum of the weighted reward terms.
        effort: mean over steps and muscles of excitation^2 (1).
        effort_sum: sum over steps and muscles of excitation^2 (1).
        reward_terms: each weighted term summed over the episode.
    """

    seed: int
    steps: int
    time_s: float
    distance_m: float
    mean_speed_m_s: float
    fell: bool
    health: str
    truncated: bool
    return_: float
    effort: float
    effort_sum: float
    reward_terms: dict[str, float]


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
    time_s: Stat
    steps: Stat
    return_: Stat
    effort: Stat
    effort_sum: Stat
    fall_rate: Rate
    failure_rate: Rate
    """episodes ended by a simulator failure (health other than "ok")"""
    health: dict[str, int]
    """episodes by the health cause they ended with ("ok" included)"""

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

        return cls(
            mode=mode,
            scene=scene.name,
            backend=backend,
            target_speed_m_s=scene.task.target_speed,
            episodes=episodes,
            distance_m=stat("distance_m"),
            mean_speed_m_s=stat("mean_speed_m_s"),
            time_s=stat("time_s"),
            steps=stat("steps"),
            return_=stat("return_"),
            effort=stat("effort"),
            effort_sum=stat("effort_sum"),
            fall_rate=Rate.of(sum(e.fell for e in episodes), n),
            failure_rate=Rate.of(sum(e.health != "ok" for e in episodes), n),
            health=dict(sorted(Counter(e.health for e in episodes).items())),
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
    recording: str | None = None
    """MCAP file of the first episode, if one was written"""
    video: str | None = None
    """MP4 file of the first episode, if one was written"""

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


# ---- running --------------------------------------------------------------------------------


def policy_sizes(policy: ActorCritic) -> tuple[int, int]:
    """(observation size, action size) a policy expects, from its description."""
    desc = policy.describe()
    if desc.get("class") == "BlendedPolicy":
        desc = desc["new"]
    return int(desc["obs_dim"]), int(desc["act_dim"])


def make_env(
    policy: ActorCritic, scene: Scene, backend: str, obs_names: list[str] | None = None
) -> MuscleEnv:
    """A ``MuscleEnv`` for ``scene`` on ``backend``, checked against the policy's sizes.

    Raises:
        EvaluationError: the backend is not one of the scene's, or the observation or action
            size differs from the policy's (naming both).
    """
    from gaitforge.workers.env import MuscleEnv  # lazy: imports the simulators

    if backend not in scene.backends:
        raise EvaluationError(f"backend {backend!r}: scene {scene.name!r} runs on {scene.backends}")
    env = MuscleEnv(scene, backend)
    obs_dim, act_dim = policy_sizes(policy)
    env_obs, env_act = env.observation_space.shape[0], env.action_space.shape[0]
    if (env_obs, env_act) != (obs_dim, act_dim):
        env.close()
        raise EvaluationError(
            f"scene {scene.name!r} on {backend} has observation size {env_obs} and action size "
            f"{env_act}; the policy expects observation size {obs_dim} and action size {act_dim}"
        )
    if obs_names is not None and list(obs_names) != env.obs_names:
        logger.warning(
            "scene %r: observation names differ from the checkpoint's (same sizes); the "
            "policy may read the wrong inputs",
            scene.name,
        )
    return env


@torch.inference_mode()
def run_episode(
    env: MuscleEnv,
    policy: ActorCritic,
    seed: int,
    mode: Mode = "deterministic",
    observer: EpisodeObserver | None = None,
) -> EpisodeResult:
    """One episode from ``env.reset(seed=seed)``; stochastic actions come from a generator
    seeded with ``seed``, so an episode repeats exactly in either mode."""
    if mode not in MODES:
        raise EvaluationError(f"mode {mode!r}: expected one of {list(MODES)}")
    generator = torch.Generator().manual_seed(seed)
    obs, _ = env.reset(seed=seed)
    if observer is not None:
        observer.on_reset(env, obs)
    steps, ret, effort_sum = 0, 0.0, 0.0
    terms: dict[str, float] = {}
    info: dict = {}
    fell = truncated = False
    health = "ok"
    while True:
        x = torch.as_tensor(obs, dtype=torch.float32).unsqueeze(0)
        if mode == "deterministic":
            action_t = policy.mean_action(x)
        else:
            dist = policy.distribution(x)
            noise = torch.randn(dist.mean.shape, generator=generator, dtype=dist.mean.dtype)
            action_t = dist.mean + dist.stddev * noise
        action = action_t[0].numpy().astype(np.float64)
        obs, reward, terminated, truncated, info = env.step(action)
        applied = np.clip(np.nan_to_num(action), 0.0, 1.0)
        steps += 1
        ret += reward
        effort_sum += float(np.sum(applied**2))
        for name, value in info.get("reward_terms", {}).items():
            terms[name] = terms.get(name, 0.0) + float(value)
        if observer is not None:
            observer.on_step(env, applied, obs, reward, info)
        health = info.get("health", "ok")
        fell = bool(info.get("fell", False))
        if terminated or truncated:
            break
    # the env's pelvis displacement since reset (at the last healthy state if the sim failed)
    distance = float(info.get("distance", 0.0))
    time_s = steps * env.dt
    n_muscles = max(1, env.action_space.shape[0])
    return EpisodeResult(
        seed=seed,
        steps=steps,
        time_s=time_s,
        distance_m=distance,
        mean_speed_m_s=distance / time_s if time_s > 0 else 0.0,
        fell=fell,
        health=health,
        truncated=bool(truncated) and not fell and health == "ok",
        return_=float(ret),
        effort=effort_sum / (steps * n_muscles) if steps else 0.0,
        effort_sum=effort_sum,
        reward_terms=terms,
    )


ProgressFn = Callable[[str, int, int], None]
"""called after each episode with (what is running, episodes done, episodes in all)"""


def evaluate_policy(
    policy: ActorCritic,
    scene: Scene,
    backend: str = "mujoco",
    *,
    episodes: int = 10,
    mode: Mode = "deterministic",
    seed: int = 0,
    env: MuscleEnv | None = None,
    observer: EpisodeObserver | None = None,
    progress: ProgressFn | None = None,
    label: str | None = None,
) -> ModeResult:
    """``episodes`` episodes (seeds ``seed .. seed + episodes - 1``) of ``policy`` on
    ``scene``; ``observer`` (if any) sees the first episode. ``env`` may be given to reuse one
    built by :func:`make_env` for this scene."""
    if episodes <= 0:
        raise EvaluationError(f"episodes must be > 0, got {episodes}")
    own_env = env is None
    env = make_env(policy, scene, backend) if env is None else env
    label = label or f"{scene.name} {mode}"
    try:
        results = []
        for i in range(episodes):
            if i == 0 and observer is not None:
                try:
                    results.append(run_episode(env, policy, seed, mode, observer))
                finally:
                    observer.close()
            else:
                results.append(run_episode(env, policy, seed + i, mode))
            if progress is not None:
                progress(label, i + 1, episodes)
    finally:
        if own_env:
            env.close()
    result = ModeResult.of(mode, scene, backend, results)
    logger.info(
        "%s: distance %.2f m, speed %.2f m/s, fall rate %.0f %%, return %.1f",
        label, result.distance_m.mean, result.mean_speed_m_s.mean, 100 * result.fall_rate.value,
        result.return_.mean,
    )  # fmt: skip
    return result


def with_target_speed(scene: Scene, target_speed: float) -> Scene:
    """``scene`` with its task's target speed (m/s) replaced (validated again)."""
    data = scene.model_dump(mode="json")
    data["task"]["target_speed"] = target_speed
    return Scene.model_validate(data)


def _check_sweep(scene: Scene, reductions: list[float]) -> float:
    """The scene's nominal target speed (m/s), once the sweep is known to make sense."""
    nominal = scene.task.target_speed
    if scene.task.kind != "locomotion" or not nominal:
        raise EvaluationError(
            f"sweep: scene {scene.name!r} has no target speed to lower (a locomotion scene "
            "with task.target_speed > 0 is needed)"
        )
    bad = [r for r in reductions if not 0.0 <= r < 1.0]
    if bad or not reductions:
        raise EvaluationError(f"sweep reductions must be fractions in [0, 1), got {reductions}")
    return nominal


def speed_sweep(
    policy: ActorCritic,
    scene: Scene,
    backend: str = "mujoco",
    *,
    reductions: Iterable[float] = DEFAULT_REDUCTIONS,
    episodes: int = 10,
    mode: Mode = "deterministic",
    seed: int = 0,
    progress: ProgressFn | None = None,
) -> list[SweepPoint]:
    """Evaluate at target speed ``(1 - r) * scene.task.target_speed`` for each reduction
    ``r`` in [0, 1) (a fraction: 0.1 is 10 % slower), same seeds at each.

    Raises:
        EvaluationError: the scene has no target speed, or a reduction is outside [0, 1).
    """
    nominal = _check_sweep(scene, reductions := list(reductions))
    points = []
    for r in reductions:
        target = nominal * (1.0 - r)
        slower = with_target_speed(scene, target)
        result = evaluate_policy(
            policy, slower, backend, episodes=episodes, mode=mode, seed=seed,
            progress=progress, label=f"{scene.name} at {target:.2f} m/s (-{100 * r:.0f} %)",
        )  # fmt: skip
        points.append(SweepPoint(r, target, result))
    return points


# ---- checkpoints ----------------------------------------------------------------------------


def resolve_checkpoint(path: Path, pick: Literal["latest", "best"] = "latest",
                       best_metric: str = "return") -> Path:  # fmt: skip
    """The checkpoint directory ``path`` names: a checkpoint itself, or a run directory (with
    ``checkpoints/`` under it) or a checkpoints directory, from which the latest or the best
    (highest ``meta["metrics"][best_metric]``) is taken.

    Raises:
        EvaluationError: nothing there, or no checkpoint under it.
    """
    if not path.exists():
        raise EvaluationError(f"{path}: no such file or directory")
    if not path.is_dir():
        raise EvaluationError(f"{path}: not a directory (a checkpoint or a run directory)")
    if (path / "manifest.json").exists() or path.name.startswith("ckpt-"):
        return path
    root = path / "checkpoints" if (path / "checkpoints").is_dir() else path
    found = checkpoints(root)
    if not found:
        raise EvaluationError(f"{path}: no checkpoint in it (looked in {root})")
    if pick == "latest":
        latest = latest_checkpoint(root)
        assert latest is not None
        return latest
    scored = []
    for ckpt in found:
        try:
            value = json.loads((ckpt / "meta.json").read_text())["metrics"][best_metric]
        except (OSError, json.JSONDecodeError, KeyError, TypeError):
            continue
        if isinstance(value, int | float) and math.isfinite(value):
            scored.append((float(value), ckpt))
    if not scored:
        raise EvaluationError(f"{root}: no checkpoint has metric {best_metric!r} to pick the best")
    return max(scored, key=lambda vc: (vc[0], vc[1].name))[1]


def _scene_of(meta: dict, path: Path, override: str | Path | Scene | None) -> Scene:
    if isinstance(override, Scene):
        return override
    if override is not None:
        try:
            return load_scene(override)
        except SpecError as exc:
            raise EvaluationError(str(exc)) from None
    if "scene" not in meta:
        raise CheckpointError(f"{path / 'meta.json'}: no 'scene'; give a scene to evaluate on")
    try:
        return Scene.model_validate(meta["scene"])
    except ValueError as exc:
        first = str(exc).splitlines()[0]
        raise CheckpointError(f"{path / 'meta.json'}: scene does not validate ({first})") from None


def evaluate_checkpoint(
    path: Path,
    *,
    scene: str | Path | Scene | None = None,
    backend: str | None = None,
    episodes: int = 10,
    modes: Sequence[Mode] = ("deterministic",),
    seed: int = 0,
    sweep: Iterable[float] | None = None,
    sweep_mode: Mode = "deterministic",
    observers: Sequence[EpisodeObserver] = (),
    record: Path | None = None,
    video: Path | None = None,
    pick: Literal["latest", "best"] = "latest",
    progress: ProgressFn | None = None,
) -> EvaluationReport:
    """Evaluate the checkpoint at ``path`` (see :func:`resolve_checkpoint`).

    Args:
        scene: a catalogue name, scene YAML or Scene to evaluate on instead of the
            checkpoint's own (its observation and action sizes must match the policy's).
        backend: simulator; default the checkpoint's ``config.backend``, else "mujoco".
        episodes: per mode and per sweep point.
        modes: action modes at the scene's own target speed.
        seed: episode ``i`` resets with ``seed + i``.
        sweep: target-speed reductions (fractions in [0, 1)) for the speed-against-safety
            sweep, run in ``sweep_mode``; None for no sweep.
        observers: see every step of the first episode (seed ``seed``) of the first mode.
        record: write that episode as an MCAP recording here (``learner.recording``).
        video: write that episode as an MP4 video here (``learner.video``).
        pick: "latest" or "best" when ``path`` is a run directory.
        progress: ``(label, done, total)`` after each episode.

    Raises:
        EvaluationError: bad path, scene, backend, sizes or options (one line).
        CheckpointError: a damaged checkpoint (naming the file).
    """
    if episodes <= 0:
        raise EvaluationError(f"episodes must be > 0, got {episodes}")
    bad = [m for m in modes if m not in MODES]
    if bad or not modes:
        raise EvaluationError(f"modes {list(modes)}: expected some of {list(MODES)}")
    if record is not None or video is not None:
        check_recording_available(record is not None, video is not None)
    ckpt = resolve_checkpoint(Path(path), pick)
    policy, meta = load_policy(ckpt)
    chosen = _scene_of(meta, ckpt, scene)
    backend = backend or meta.get("config", {}).get("backend") or "mujoco"
    sweep_list = None if sweep is None else list(sweep)
    if sweep_list is not None:
        _check_sweep(chosen, sweep_list)
    results: dict[str, ModeResult] = {}
    for k, mode in enumerate(modes):
        env = make_env(policy, chosen, backend, meta.get("obs_names") if scene else None)
        try:
            watching: list[EpisodeObserver] = []
            if k == 0:
                watching = list(observers)
                info = recording_metadata(ckpt, mode, seed)
                if record is not None:
                    watching.append(McapObserver(record, env, info))
                if video is not None:
                    watching.append(VideoObserver(video, env))
            observer = Fanout(watching) if watching else None
            results[mode] = evaluate_policy(
                policy, chosen, backend, episodes=episodes, mode=mode, seed=seed, env=env,
                observer=observer, progress=progress,
            )  # fmt: skip
        finally:
            env.close()
    points: list[SweepPoint] = []
    if sweep_list is not None:
        points = speed_sweep(
            policy, chosen, backend, reductions=sweep_list, episodes=episodes, mode=sweep_mode,
            seed=seed, progress=progress,
        )  # fmt: skip
    return EvaluationReport(
        checkpoint=str(ckpt),
        env_steps=meta.get("env_steps"),
        scene=chosen.name,
        backend=backend,
        seed=seed,
        results=results,
        sweep=points,
        sweep_mode=sweep_mode if sweep_list is not None else None,
        stage=meta.get("stage"),
        recording=None if record is None else str(record),
        video=None if video is None else str(video),
    )
