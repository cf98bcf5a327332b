"""Evaluation: run a checkpoint's policy on its scene (or another with the same sizes) for N
episodes with fixed seeds and report distance, speed, falls, effort, return and health.

Two action modes: ``deterministic`` (the policy's mean excitation) and ``stochastic`` (a
sample from its Gaussian, drawn from a generator seeded per episode, so a stochastic
evaluation repeats exactly too). Episode ``i`` resets the env with seed ``seed + i`` in every
mode and at every sweep point: the modes and speeds are compared on the same initial states.

The *speed-against-safety sweep* lowers the scene's target speed (m/s) by fractions (0, 10,
20, 30 % by default) and evaluates at each: the target speed is in the observation, so the
same policy is asked to go slower, and the fall rate at each speed says what speed buys.

Everything runs in-process on one env (no Ray), through the one episode loop
(``workers.episode``): the statistics are an observer (``learner.eval_observers``), and so are
the MCAP recording and the video of the first episode. Results are dataclasses
(``learner.evaluate_results``, units there); ``to_dict()`` gives JSON-able dicts and
:func:`write_json` a file.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
import torch
from gaitforge.learner.checkpoint import checkpoints, load_policy, select_checkpoint
from gaitforge.learner.checkpoint_meta import META_FILE, CheckpointMeta
from gaitforge.learner.eval_observers import (
    EpisodeMetrics,
    EvaluationError,
    check_recording_available,
    mcap_observer,
    recording_metadata,
    video_observer,
)
from gaitforge.learner.evaluate_results import (
    MODES,
    EpisodeResult,
    EvaluationReport,
    Mode,
    ModeResult,
    SweepPoint,
    write_json,
)
from gaitforge.learner.policy import ActorCritic
from gaitforge.workers.episode import Act, EpisodeObserver, EpisodeRunner
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError

__all__ = [
    "MODES",
    "EpisodeResult",
    "EvaluationError",
    "EvaluationReport",
    "Mode",
    "ModeResult",
    "SweepPoint",
    "evaluate_checkpoint",
    "evaluate_episode",
    "evaluate_policy",
    "make_runner",
    "policy_act",
    "resolve_checkpoint",
    "speed_sweep",
    "with_target_speed",
    "write_json",
]

logger = logging.getLogger(__name__)

DEFAULT_REDUCTIONS: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3)
"""fractions by which the sweep lowers the target speed"""


# ---- running --------------------------------------------------------------------------------


def policy_sizes(policy: ActorCritic) -> tuple[int, int]:
    """(observation size, action size) a policy expects, from its description."""
    desc = policy.describe()
    if desc.get("class") == "BlendedPolicy":
        desc = desc["new"]
    return int(desc["obs_dim"]), int(desc["act_dim"])


def make_runner(
    policy: ActorCritic, scene: Scene, backend: str, obs_names: list[str] | None = None
) -> EpisodeRunner:
    """An :class:`EpisodeRunner` (one env) for ``scene`` on ``backend``, checked against the
    policy's sizes; a warning if ``obs_names`` (the checkpoint's) differ from the env's.

    Raises:
        EvaluationError: the backend is not one of the scene's, or the observation or action
            size differs from the policy's (naming both).
    """
    if backend not in scene.backends:
        raise EvaluationError(f"backend {backend!r}: scene {scene.name!r} runs on {scene.backends}")
    runner = EpisodeRunner(scene, backend)
    obs_dim, act_dim = policy_sizes(policy)
    env_obs, env_act = len(runner.obs_names), len(runner.act_names)
    if (env_obs, env_act) != (obs_dim, act_dim):
        runner.close()
        raise EvaluationError(
            f"scene {scene.name!r} on {backend} has observation size {env_obs} and action size "
            f"{env_act}; the policy expects observation size {obs_dim} and action size {act_dim}"
        )
    if obs_names is not None and list(obs_names) != runner.obs_names:
        logger.warning(
            "scene %r: observation names differ from the checkpoint's (same sizes); the "
            "policy may read the wrong inputs",
            scene.name,
        )
    return runner


def policy_act(policy: ActorCritic, mode: Mode, seed: int) -> Act:
    """``policy`` as an episode's actions: observation [n_obs] -> excitations [n_muscles]
    (float64), the mean in ``deterministic`` mode, else a sample drawn with a generator seeded
    with ``seed`` (so an episode repeats exactly in either mode)."""
    if mode not in MODES:
        raise EvaluationError(f"mode {mode!r}: expected one of {list(MODES)}")
    generator = torch.Generator().manual_seed(seed)

    @torch.inference_mode()
    def act(obs: np.ndarray) -> np.ndarray:
        x = torch.as_tensor(obs, dtype=torch.float32).unsqueeze(0)
        if mode == "deterministic":
            action = policy.mean_action(x)
        else:
            dist = policy.distribution(x)
            noise = torch.randn(dist.mean.shape, generator=generator, dtype=dist.mean.dtype)
            action = dist.mean + dist.stddev * noise
        return action[0].numpy().astype(np.float64)

    return act


def evaluate_episode(
    runner: EpisodeRunner,
    policy: ActorCritic,
    seed: int,
    mode: Mode = "deterministic",
    observers: Sequence[EpisodeObserver] = (),
) -> EpisodeResult:
    """One episode from ``reset(seed=seed)`` (stochastic actions seeded with ``seed`` too),
    shown to ``observers`` besides the statistics."""
    metrics = EpisodeMetrics()
    runner.run(policy_act(policy, mode, seed), seed, [metrics, *observers])
    assert metrics.result is not None
    return metrics.result


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
    runner: EpisodeRunner | None = None,
    observers: Sequence[EpisodeObserver] = (),
    progress: ProgressFn | None = None,
    label: str | None = None,
) -> ModeResult:
    """``episodes`` episodes (seeds ``seed .. seed + episodes - 1``) of ``policy`` on
    ``scene``; ``observers`` see the first episode. ``runner`` may be given to reuse one
    built by :func:`make_runner` for this scene (it stays open)."""
    if episodes <= 0:
        raise EvaluationError(f"episodes must be > 0, got {episodes}")
    own_runner = runner is None
    runner = make_runner(policy, scene, backend) if runner is None else runner
    label = label or f"{scene.name} {mode}"
    try:
        results = []
        for i in range(episodes):
            watching = observers if i == 0 else ()
            results.append(evaluate_episode(runner, policy, seed + i, mode, watching))
            if progress is not None:
                progress(label, i + 1, episodes)
    finally:
        if own_runner:
            runner.close()
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
    (highest ``metrics[best_metric]``) is taken (``learner.checkpoint.select_checkpoint``).

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
    if not checkpoints(root):
        raise EvaluationError(f"{path}: no checkpoint in it (looked in {root})")
    chosen = select_checkpoint(root, pick, best_metric)
    if chosen is None:
        raise EvaluationError(f"{root}: no checkpoint has metric {best_metric!r} to pick the best")
    return chosen


def _scene_of(meta: CheckpointMeta, path: Path, override: str | Path | Scene | None) -> Scene:
    """The scene to evaluate on, resolved here (``Scene.resolved``), where it is loaded."""
    if isinstance(override, Scene):
        scene = override
    elif override is not None:
        try:
            scene = load_scene(override)
        except SpecError as exc:
            raise EvaluationError(str(exc)) from None
    else:
        scene = meta.scene_spec(path / META_FILE)
    try:
        return scene.resolved()
    except ValueError as exc:
        raise EvaluationError(f"{path}: {exc}") from None


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
    backend = backend or meta.backend
    sweep_list = None if sweep is None else list(sweep)
    if sweep_list is not None:
        _check_sweep(chosen, sweep_list)
    results: dict[str, ModeResult] = {}
    for k, mode in enumerate(modes):
        with make_runner(policy, chosen, backend, meta.obs_names if scene else None) as run:
            watching: list[EpisodeObserver] = []
            if k == 0:
                watching = list(observers)
                info = recording_metadata(ckpt, mode, seed)
                try:
                    if record is not None:
                        watching.append(mcap_observer(record, run.env, info))
                    if video is not None:
                        watching.append(video_observer(video, run.env))
                except BaseException:
                    for observer in watching[len(observers) :]:
                        observer.on_end(None)  # close the recording already opened
                    raise
            results[mode] = evaluate_policy(
                policy, chosen, backend, episodes=episodes, mode=mode, seed=seed, runner=run,
                observers=watching, progress=progress,
            )  # fmt: skip
    points: list[SweepPoint] = []
    if sweep_list is not None:
        points = speed_sweep(
            policy, chosen, backend, reductions=sweep_list, episodes=episodes, mode=sweep_mode,
            seed=seed, progress=progress,
        )  # fmt: skip
    return EvaluationReport(
        checkpoint=str(ckpt),
        env_steps=meta.env_steps,
        scene=chosen.name,
        backend=backend,
        seed=seed,
        results=results,
        sweep=points,
        sweep_mode=sweep_mode if sweep_list is not None else None,
        stage=None if meta.stage is None else meta.stage.model_dump(),
        recording=None if record is None else str(record),
        video=None if video is None else str(video),
    )
