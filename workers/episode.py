"""The one episode loop: a policy's actions on one env from reset to the end, watched by
observers.

Evaluation statistics, MCAP recordings and videos are observers of this loop (in
``gaitforge.learner``); nothing else steps an env for whole episodes. Training samples only
through the pool (``workers.pool``), so :class:`EpisodeRunner` and the pool's actors are the
only places where the learner's envs are built.

An observer sees, in order: ``on_reset`` once after ``env.reset``, ``on_step`` after every
``env.step`` (the simulator still holds that step's state, so an observer may read it), and
``on_end`` exactly once, with the episode's :class:`EpisodeSummary`, or with None when the
episode stopped on an exception (an observer releases its files either way).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Protocol, Self

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene
from gaitforge.workers.sim.base import HEALTHY

logger = logging.getLogger(__name__)

Act = Callable[[np.ndarray], np.ndarray]
"""A policy: observation [n_obs] (float32) -> excitations [n_muscles] (clipped to [0, 1] by
the env when applied)."""


@dataclass(frozen=True)
class EpisodeSummary:
    """One episode, as the env reported it.

    Attributes:
        seed: the env's reset seed.
        steps: control steps taken.
        time_s: control time, s (``steps / control_hz``).
        sim_time_s: the simulator's clock at the end, s (``info["sim_time"]``; 0 with no step).
        return_: sum of the step rewards (the scene's weighted reward terms).
        distance_m: pelvis forward displacement since reset, m (at the last healthy state if
            the simulator failed).
        turned_rad: the pelvis's turn about the vertical since reset, rad, counter-clockwise
            seen from above (0 on a planar body; at the last healthy state likewise).
        fell: the episode ended by a fall (pelvis below ``task.min_pelvis_height``).
        health: the health cause of the last step ("ok" unless the simulator failed).
        terminated: the env ended the episode (a fall or a simulator failure).
        truncated: the env cut the episode at ``episode_s``. Both are False when the loop
            stopped at ``max_steps``.
    """

    seed: int
    steps: int
    time_s: float
    sim_time_s: float
    return_: float
    distance_m: float
    turned_rad: float
    fell: bool
    health: str
    terminated: bool
    truncated: bool


class EpisodeObserver(Protocol):
    """What watches an episode (see the module's docstring for the order of calls)."""

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        """After ``env.reset``: the first observation [n_obs] and the reset's info."""

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
        """After ``env.step``: ``action`` [n_muscles] is the excitation as applied (clipped
        to [0, 1], float64); the rest is what the step returned."""

    def on_end(self, summary: EpisodeSummary | None) -> None:
        """Once, at the end; None when the episode stopped on an exception."""


class Observer:
    """An :class:`EpisodeObserver` that does nothing: subclass it and override what is needed."""

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        pass

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
        pass

    def on_end(self, summary: EpisodeSummary | None) -> None:
        pass


class ClosingObserver(Observer):
    """An observer that owns a resource (a file, a renderer): the episode's end and a
    ``with`` block both :meth:`close` it; ``close`` must be idempotent."""

    def close(self) -> None:
        raise NotImplementedError

    def on_end(self, summary: EpisodeSummary | None) -> None:
        self.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _end(observers: Sequence[EpisodeObserver], summary: EpisodeSummary | None) -> None:
    """``on_end`` on every observer, even if one fails; then raise the first failure (or
    only log them, when the episode itself failed: its exception goes on)."""
    errors: list[BaseException] = []
    for observer in observers:
        try:
            observer.on_end(summary)
        except Exception as exc:
            errors.append(exc)
    if errors and summary is not None:
        raise errors[0]
    for exc in errors:
        logger.error("episode observer %s failed at the end: %s", type(exc).__name__, exc)


def run_episode(
    env: MuscleEnv,
    act: Act,
    seed: int,
    observers: Sequence[EpisodeObserver] = (),
    max_steps: int | None = None,
) -> EpisodeSummary:
    """One episode of ``act`` on ``env`` from ``env.reset(seed=seed)`` until the env ends it
    (fall, simulator failure, ``episode_s``) or ``max_steps`` steps, shown to ``observers``."""
    try:
        obs, info = env.reset(seed=seed)
        for observer in observers:
            observer.on_reset(env, obs, info)
        steps, total = 0, 0.0
        terminated = truncated = False
        while max_steps is None or steps < max_steps:
            action = np.asarray(act(obs), dtype=np.float64)
            obs, reward, terminated, truncated, info = env.step(action)
            steps += 1
            total += reward
            applied = np.clip(np.nan_to_num(action), 0.0, 1.0)
            for observer in observers:
                observer.on_step(env, applied, obs, reward, terminated, truncated, info)
            if terminated or truncated:
                break
        summary = EpisodeSummary(
            seed=seed,
            steps=steps,
            time_s=steps * env.dt,
            sim_time_s=float(info.get("sim_time", 0.0)),
            return_=float(total),
            distance_m=float(info.get("distance", 0.0)),
            turned_rad=float(info.get("turned", 0.0)),
            fell=bool(info.get("fell", False)),
            health=str(info.get("health", HEALTHY)),
            terminated=bool(terminated),
            truncated=bool(truncated),
        )
    except BaseException:
        _end(observers, None)
        raise
    _end(observers, summary)
    return summary


class EpisodeRunner:
    """One :class:`MuscleEnv` of ``scene`` on ``backend``, for whole episodes.

    Owns the env (closed by :meth:`close` or a ``with`` block); ``env`` is there for
    observers that need it when they are built (a recorder reads the simulator's names).
    """

    def __init__(self, scene: str | Scene, backend: str = "mujoco") -> None:
        self.env = MuscleEnv(scene, backend)

    @property
    def scene(self) -> Scene:
        return self.env.scene

    @property
    def backend(self) -> str:
        return self.env.backend

    @property
    def obs_names(self) -> list[str]:
        """Names of the observation's entries [n_obs] (see ``workers.env``)."""
        return list(self.env.obs_names)

    @property
    def act_names(self) -> list[str]:
        """Names of the action's entries: the kept muscles [n_muscles], or ``target:<dof>``
        [n_dofs] for a scene whose action is joint targets."""
        return list(self.env.act_names)

    def run(
        self,
        act: Act,
        seed: int,
        observers: Sequence[EpisodeObserver] = (),
        max_steps: int | None = None,
    ) -> EpisodeSummary:
        """One episode (see :func:`run_episode`)."""
        return run_episode(self.env, act, seed, observers, max_steps)

    def close(self) -> None:
        self.env.close()

    def __enter__(self) -> EpisodeRunner:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
