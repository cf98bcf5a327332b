"""A rollout worker: K envs of one scene and a CPU copy of the policy, stepped in lockstep.

``RolloutWorker`` is a plain class (used in-process by learner tests) that the pool wraps
with ``ray.remote``. Each ``sample`` call returns one fixed-length
:class:`~gaitforge.workers.fragment.Fragment` (numpy arrays with leading dimensions
``[T, K]``; its docstring gives every array). Policy inference is batched over the K envs,
one torch thread.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.gait_measure import CandidateScore, GaitMeasure, score_candidate
from gaitforge.workers.policy_api import RolloutPolicy
from gaitforge.workers.probe import process_rss_mib
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile

logger = logging.getLogger(__name__)

PolicyFactory = Callable[[], RolloutPolicy]


@dataclass
class _EpisodeTally:
    ret: float = 0.0
    length: int = 0


class RolloutWorker:
    """Owns ``num_envs`` envs of ``scene`` on ``backend`` and a policy copy. The scene must
    be resolved (``Scene.resolved``, on the driver): an actor looks up no fidelity profile."""

    def __init__(
        self,
        scene: Scene,
        policy_factory: PolicyFactory,
        *,
        backend: str = "mujoco",
        num_envs: int = 4,
        fragment_length: int = 64,
        seed: int = 0,
        worker_id: int = 0,
    ) -> None:
        torch.set_num_threads(1)
        torch.manual_seed(seed)
        self.worker_id = worker_id
        self.fragment_length = fragment_length
        self.backend = backend
        self.seed = seed
        self.policy = policy_factory()
        self.policy_version = -1
        self.steps_total = 0
        self._build_envs(scene, num_envs)

    def _build_envs(self, scene: Scene, num_envs: int) -> None:
        self.scene = scene.require_resolved("RolloutWorker")
        self.envs = [MuscleEnv(scene, self.backend) for _ in range(num_envs)]
        self._obs = np.stack(
            [env.reset(seed=self.seed * 10_000 + i)[0] for i, env in enumerate(self.envs)]
        )
        self._tally = [_EpisodeTally() for _ in self.envs]

    # ---- remote API ---------------------------------------------------------------------

    def set_scene(self, scene: Scene, backend: str | None = None) -> None:
        """Switch every env to ``scene`` (a curriculum stage), on ``backend`` if given (a
        stage on another simulator); episodes restart."""
        self.backend = backend or self.backend
        self._build_envs(scene, len(self.envs))

    def set_policy(self, policy_factory: PolicyFactory) -> None:
        """Replace the policy's structure (a new network at a curriculum stage); weights
        follow with the next request."""
        self.policy = policy_factory()
        self.policy_version = -1

    def set_weights(self, weights: dict[str, torch.Tensor], version: int) -> None:
        if version != self.policy_version:
            self.policy.load_state_dict(weights)
            self.policy_version = version

    def sample(self, weights: dict[str, torch.Tensor] | None = None, version: int = -1) -> Fragment:
        """One fragment ``[T, K, ...]``; loads ``weights`` first if ``version`` is new."""
        if weights is not None:
            self.set_weights(weights, version)
        start = time.perf_counter()
        t_len, k = self.fragment_length, len(self.envs)
        obs_dim = self._obs.shape[1]
        act_dim = self.envs[0].action_space.shape[0]
        obs_out = np.zeros((t_len, k, obs_dim), np.float32)
        action_out = np.zeros((t_len, k, act_dim), np.float32)
        logp_out = np.zeros((t_len, k), np.float32)
        value_out = np.zeros((t_len, k), np.float32)
        reward_out = np.zeros((t_len, k), np.float32)
        terminated_out = np.zeros((t_len, k), bool)
        truncated_out = np.zeros((t_len, k), bool)
        unhealthy_out = np.zeros((t_len, k), bool)
        bootstrap_out = np.zeros((t_len, k), np.float32)
        episodes: list[tuple[float, int, float, bool]] = []
        health: Counter[str] = Counter()
        term_sums: Counter[str] = Counter()
        for t in range(t_len):
            with torch.no_grad():
                action, logp, value = self.policy.act(torch.from_numpy(self._obs))
            actions = action.numpy()
            obs_out[t], action_out[t] = self._obs, actions
            logp_out[t], value_out[t] = logp.numpy(), value.numpy()
            final_obs: dict[int, np.ndarray] = {}
            for i, env in enumerate(self.envs):
                obs, reward, terminated, truncated, info = env.step(actions[i])
                reward_out[t, i] = reward
                terminated_out[t, i], truncated_out[t, i] = terminated, truncated
                tally = self._tally[i]
                tally.ret += reward
                tally.length += 1
                term_sums.update(info["reward_terms"])
                if info["health"] != "ok":
                    unhealthy_out[t, i] = True
                    health[info["health"]] += 1
                if terminated or truncated:
                    episodes.append(
                        (tally.ret, tally.length, info["distance"], bool(info.get("fell")))
                    )
                    self._tally[i] = _EpisodeTally()
                    if truncated and not terminated:
                        final_obs[i] = obs
                    obs, _ = env.reset()
                self._obs[i] = obs
            if final_obs:
                with torch.no_grad():
                    values = self.policy.value(torch.from_numpy(np.stack(list(final_obs.values()))))
                for i, v in zip(final_obs, values.numpy(), strict=True):
                    bootstrap_out[t, i] = v
        with torch.no_grad():
            last_value = self.policy.value(torch.from_numpy(self._obs)).numpy()
        stats = np.array(episodes, dtype=float).reshape(-1, 4)
        self.steps_total += t_len * k
        return Fragment(
            obs=obs_out,
            action=action_out,
            logp=logp_out,
            value=value_out,
            reward=reward_out,
            terminated=terminated_out,
            truncated=truncated_out,
            unhealthy=unhealthy_out,
            bootstrap_value=bootstrap_out,
            last_obs=self._obs.copy(),
            last_value=last_value,
            episode_return=stats[:, 0],
            episode_length=stats[:, 1].astype(np.int64),
            episode_distance=stats[:, 2],
            episode_fell=stats[:, 3].astype(bool),
            health=dict(health),
            reward_terms={name: total / (t_len * k) for name, total in term_sums.items()},
            policy_version=self.policy_version,
            worker=self.worker_id,
            steps=t_len * k,
            wall_s=time.perf_counter() - start,
            worker_steps_total=self.steps_total,
            rss_mib=process_rss_mib(),
            pid=os.getpid(),
        )

    def score(
        self, parameters: np.ndarray, seeds: list[int], measure: GaitMeasure
    ) -> CandidateScore:
        """One reflex controller candidate's score: ``parameters`` [n_parameters], one
        episode per seed on the first env (``workers.gait_measure.score_candidate``)."""
        score = score_candidate(self.envs[0], parameters, seeds, measure)
        self.steps_total += score.env_steps
        return score

    def score_candidates(
        self,
        candidates: list[np.ndarray],
        seeds: list[int],
        measure: GaitMeasure,
        stop: threading.Event | None = None,
    ) -> list[CandidateScore]:
        """Each candidate's :meth:`score`, in order, in this process (``WorkerPool``'s
        counterpart; a ``workers.gait_measure.CandidateScorer``).

        Raises:
            StopRequested: ``stop`` was set (looked at between candidates).
        """
        scores = []
        for parameters in candidates:
            if stop is not None and stop.is_set():
                raise StopRequested
            scores.append(self.score(parameters, seeds, measure))
        return scores

    def sim_profile(self) -> FidelityProfile:
        """The fidelity profile this worker's simulators integrate with."""
        return self.envs[0].sim.report.profile

    def node_id(self) -> str:
        """The Ray node this worker runs on ("local" outside Ray)."""
        try:
            import ray  # lazy: the in-process mode needs no Ray

            return ray.get_runtime_context().get_node_id()
        except Exception:  # no Ray runtime here
            return "local"
