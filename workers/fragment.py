"""What a rollout worker hands the learner: a :class:`Fragment` of ``T`` control steps of ``K``
envs stepped in lockstep. Imports no other gaitforge module, so the workers (which make
fragments) and the learner (which reads them) share it without depending on each other.

Fragments cross Ray as pickles of numpy arrays (no copies beyond Ray's own serialisation).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class StopRequested(Exception):
    """A stop was requested while a fragment was awaited: the wait ends without one."""


@dataclass(frozen=True, kw_only=True, eq=False)
class Fragment:
    """``T`` control steps of ``K`` envs (``RolloutWorker.sample``). ``t`` indexes time, ``k``
    the env; ``E`` is the number of episodes that ended within the fragment.

    Per step, ``[T, K, ...]``:

    - ``obs`` ``[T, K, obs_dim]`` float32: the observation the action was taken on;
    - ``action`` ``[T, K, act_dim]`` float32: excitations as the policy drew them (the env
      clips them to [0, 1]);
    - ``logp`` ``[T, K]`` float32: the action's log-probability under the acting policy (nats);
    - ``value`` ``[T, K]`` float32: the critic's value of ``obs`` (return units);
    - ``reward`` ``[T, K]`` float32: the step's reward (sum of the scene's weighted terms);
    - ``terminated`` ``[T, K]`` bool: the episode ended on this step (fall, failure, goal);
    - ``truncated`` ``[T, K]`` bool: the episode ran out of time on this step;
    - ``unhealthy`` ``[T, K]`` bool: the step was ended by a simulator failure (then also
      ``terminated``; the cause is counted in ``health``);
    - ``bootstrap_value`` ``[T, K]`` float32: the value of the final observation where
      ``truncated`` and not ``terminated``, else 0.

    At the fragment's end, ``[K, ...]``:

    - ``last_obs`` ``[K, obs_dim]`` float32: the observation after the last step (the env
      was reset where an episode ended on it);
    - ``last_value`` ``[K]`` float32: its value, to bootstrap the fragment's end.

    Per finished episode, ``[E]``, in the order they ended:

    - ``episode_return`` float64: undiscounted return;
    - ``episode_length`` int64: control steps (``length / control_hz`` seconds);
    - ``episode_distance`` float64: distance covered (m) along the scene's forward axis;
    - ``episode_fell`` bool: it ended with a fall.

    Scalars and counts: ``health`` (failure cause -> steps), ``reward_terms`` (term -> mean
    weighted value per env step), ``policy_version`` (the weights' version that acted, -1 for
    the initial ones), ``worker`` (the worker's id), ``steps`` (``T * K`` env steps),
    ``wall_s`` (seconds the fragment took), ``worker_steps_total`` (env steps the worker has
    made since it started), ``rss_mib`` (the worker process's resident memory, MiB), ``pid``.
    """

    obs: np.ndarray
    action: np.ndarray
    logp: np.ndarray
    value: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    unhealthy: np.ndarray
    bootstrap_value: np.ndarray
    last_obs: np.ndarray
    last_value: np.ndarray
    episode_return: np.ndarray
    episode_length: np.ndarray
    episode_distance: np.ndarray
    episode_fell: np.ndarray
    health: dict[str, int] = field(default_factory=dict)
    reward_terms: dict[str, float] = field(default_factory=dict)
    policy_version: int = -1
    worker: int = 0
    steps: int = 0
    wall_s: float = 0.0
    worker_steps_total: int = 0
    rss_mib: float = 0.0
    pid: int = 0

    STEP_ARRAYS = (
        "obs",
        "action",
        "logp",
        "value",
        "reward",
        "terminated",
        "truncated",
        "unhealthy",
        "bootstrap_value",
    )
    """the ``[T, K, ...]`` arrays"""
    EPISODE_ARRAYS = ("episode_return", "episode_length", "episode_distance", "episode_fell")
    """the ``[E]`` arrays"""

    def __post_init__(self) -> None:
        t_k = self.obs.shape[:2]
        bad = [n for n in self.STEP_ARRAYS if getattr(self, n).shape[:2] != t_k]
        bad += [n for n in ("last_obs", "last_value") if getattr(self, n).shape[:1] != t_k[1:]]
        e = self.episode_return.shape
        bad += [n for n in self.EPISODE_ARRAYS if getattr(self, n).shape != e]
        if bad:
            raise ValueError(f"fragment arrays {bad} do not fit obs [T, K] = {list(t_k)}")

    @property
    def length(self) -> int:
        """``T``: control steps per env."""
        return self.obs.shape[0]

    @property
    def num_envs(self) -> int:
        """``K``: envs stepped in lockstep."""
        return self.obs.shape[1]

    @property
    def episodes(self) -> int:
        """``E``: episodes that ended in the fragment."""
        return len(self.episode_return)

    def flat_obs(self) -> np.ndarray:
        """``obs`` as ``[T * K, obs_dim]`` (a view)."""
        return self.obs.reshape(-1, self.obs.shape[-1])


__all__ = ["Fragment"]
