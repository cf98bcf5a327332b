"""Evaluation of a policy on a scene: N episodes through the one episode loop
(``workers.episode``) with the statistics as an observer, in a deterministic or stochastic
action mode, and the speed-against-safety sweep (see ``learner.evaluation.evaluate`` for the whole).

Episode ``i`` resets with seed ``seed + i``; stochastic actions are drawn from a generator
seeded per episode, so every evaluation repeats exactly.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence

import numpy as np
import torch
from gaitforge.learner.evaluation.observers import EpisodeMetrics, EvaluationError
from gaitforge.learner.evaluation.results import (
    MODES,
    EpisodeResult,
    Mode,
    ModeResult,
    SweepPoint,
)
from gaitforge.learner.policy import ActorCritic
from gaitforge.workers.episode import Act, EpisodeObserver, EpisodeRunner
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)

DEFAULT_REDUCTIONS: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3)
"""fractions by which the sweep lowers the target speed"""


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
        label,
        result.distance_m.mean,
        result.mean_speed_m_s.mean,
        100 * result.fall_rate.value,
        result.return_.mean,
    )
    if result.turned:
        logger.info("%s: the pelvis turned %.0f deg on average", label, result.turned_deg.mean)
    if result.tracking_error_rad is not None and result.kept_gait_rate is not None:
        logger.info(
            "%s: tracking error %.3f rad, kept the gait in %.0f %% of episodes",
            label,
            result.tracking_error_rad.mean,
            100 * result.kept_gait_rate.value,
        )
    if result.touched_rate is not None:
        logger.info(
            "%s: a foot touched an obstacle in %d of %d episodes; falls %d of them, %d of the "
            "others",
            label,
            result.touched_rate.count,
            len(results),
            result.fall_rate_touched.count,
            result.fall_rate_untouched.count,
        )
    return result


def with_target_speed(scene: Scene, target_speed: float) -> Scene:
    """``scene`` with its task's target speed (m/s) replaced (validated again); a scene that
    draws it each episode (``task.target_speed_range``) draws ``target_speed`` every time,
    its clock's tempo scaled from the scene's ``target_speed`` as in training."""
    data = scene.model_dump(mode="json")
    if scene.task.target_speed_range is not None:
        data["task"]["target_speed_range"] = (target_speed, target_speed)
    else:
        data["task"]["target_speed"] = target_speed
    return Scene.model_validate(data)


def check_sweep(scene: Scene, reductions: list[float]) -> float:
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


def one_pace_note(trained: Scene, chosen: Scene, sweep: bool) -> str | None:
    """Why figures at another target speed say little about following it, or None: the
    policy was trained at one target speed (``trained``, the checkpoint's scene, draws no
    ``task.target_speed_range``) and ``chosen`` asks for another (a different target speed or
    a drawn one), or a ``sweep`` lowers it."""
    task = trained.task
    if task.kind != "locomotion" or not task.target_speed or task.target_speed_range:
        return None
    asked = chosen.task
    other = asked.target_speed_range is not None or asked.target_speed != task.target_speed
    if not (other or sweep):
        return None
    return (
        f"the policy was trained at one target speed ({task.target_speed:g} m/s: scene "
        f"{trained.name!r} draws no task.target_speed_range), so it keeps its pace whatever "
        "target it is given; a policy trained with the speed-range option follows the target"
    )


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
    nominal = check_sweep(scene, reductions := list(reductions))
    points = []
    for r in reductions:
        target = nominal * (1.0 - r)
        slower = with_target_speed(scene, target)
        result = evaluate_policy(
            policy,
            slower,
            backend,
            episodes=episodes,
            mode=mode,
            seed=seed,
            progress=progress,
            label=f"{scene.name} at {target:.2f} m/s (-{100 * r:.0f} %)",
        )
        points.append(SweepPoint(r, target, result))
    return points
