"""RLlib's PPO on a gaitforge job, for ``bench/learning.py``: the job's stages in order on the
same scenes (each stage's env-step budget, then its scene is pushed to every env runner),
the same network, batch, minibatch, epochs, learning rate, discount, GAE lambda and clip,
RLlib's defaults otherwise (no observation filter, actions squashed to the env's bounds).
The target is the last stage's promotion rules, judged after each iteration on episode
statistics kept the way gaitforge's curriculum keeps them (a callback), over the rules'
largest window; at the end the trained module's mean action is evaluated deterministically
by gaitforge's own evaluation (``learner.evaluate_policy``), as gaitforge's runs are.
"""

from __future__ import annotations

import logging
import time

import torch
from gaitforge.learner.evaluation.evaluate import EvaluationReport, evaluate_policy
from gaitforge.learner.job import METRICS, Job
from gaitforge.learner.metrics import Episode
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene
from rich.console import Console

console = Console()
RLLIB_ENV = "gaitforge-learning"


def env_config(job: Job, scenes: list[Scene], stage: int) -> dict:
    """What an env runner builds its envs from in ``stage``: the scene, backend and the two
    figures the episode callback needs."""
    scene = scenes[stage]
    return {
        "scene": scene.model_dump(mode="json"),
        "backend": job.stage_backend(stage),
        "control_hz": scene.control_hz,
        "steps_per_episode": scene.steps_per_episode,
    }


class RLlibMeanPolicy:
    """An RLlib PPO module as gaitforge's evaluation sees a policy: ``describe`` gives its
    sizes and ``mean_action`` [batch, n_obs] -> [batch, n_act] its mean action, unsquashed
    from RLlib's [-1, 1] to its action space's bounds as RLlib does when it samples."""

    def __init__(self, module) -> None:
        self.module = module
        self.obs_dim = int(module.observation_space.shape[0])
        self.act_dim = int(module.action_space.shape[0])
        self.low = torch.as_tensor(module.action_space.low, dtype=torch.float32)
        self.high = torch.as_tensor(module.action_space.high, dtype=torch.float32)

    def describe(self) -> dict:
        return {"class": "RLlibMeanPolicy", "obs_dim": self.obs_dim, "act_dim": self.act_dim}

    @torch.inference_mode()
    def mean_action(self, obs: torch.Tensor) -> torch.Tensor:
        out = self.module.forward_inference({"obs": obs})
        mean = out["action_dist_inputs"][:, : self.act_dim]
        squashed = self.low + (mean + 1.0) * (self.high - self.low) / 2.0
        return torch.clamp(squashed, self.low, self.high)


def run_rllib(
    job: Job, scenes: list[Scene], minutes: float, workers: int, eval_episodes: int
) -> tuple[list[dict], bool, dict | None]:
    """RLlib on ``job`` for ``minutes`` of wall clock (set-up included) with ``workers`` env
    runners. Returns the curve (one point per iteration: wall_s, env_steps, stage, return
    and the rules' metrics), whether the last stage's rules passed, and with
    ``eval_episodes`` the deterministic evaluation of the final module on the last stage
    reached (``ModeResult.to_dict()`` less its episodes), else None."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.callbacks.callbacks import RLlibCallback
    from ray.tune.registry import register_env

    logging.getLogger("ray.rllib").setLevel(logging.ERROR)
    register_env(
        RLLIB_ENV, lambda cfg: MuscleEnv(Scene.model_validate(cfg["scene"]), cfg["backend"])
    )
    last = len(job.stages) - 1
    rules = job.stages[last].promote
    window = max(rule.window for rule in rules)

    class EpisodeLog(RLlibCallback):
        """Each finished episode's statistics as the gaitforge trainer keeps them, as means
        over the last ``window`` episodes."""

        def on_episode_end(self, *, episode, env_runner, metrics_logger, **kwargs) -> None:
            info = episode.get_infos()[-1]
            length = len(episode)
            cfg = env_runner.config.env_config
            stats = Episode(
                float(episode.get_return()),
                float(info.get("distance", 0.0)),
                length / cfg["control_hz"],
                bool(info.get("fell", False)),
                length >= cfg["steps_per_episode"],
            )
            for metric in METRICS:
                metrics_logger.log_value(f"gf_{metric}", stats.metric(metric), window=window)

    ppo = job.ppo
    config = (
        PPOConfig()
        .environment(RLLIB_ENV, env_config=env_config(job, scenes, 0))
        .env_runners(num_env_runners=workers, num_envs_per_env_runner=job.workers.envs_per_worker)
        .training(
            train_batch_size_per_learner=ppo.batch_env_steps,
            minibatch_size=ppo.minibatch_size,
            num_epochs=ppo.epochs,
            lr=ppo.lr,
            gamma=ppo.gamma,
            lambda_=ppo.lam,
            clip_param=ppo.clip,
        )
        .rl_module(
            model_config={"fcnet_hiddens": list(job.network.hidden), "fcnet_activation": "tanh"}
        )
        .callbacks(EpisodeLog)
        .debugging(seed=job.seed)
    )
    start = time.monotonic()  # set-up counts, as it does for gaitforge
    algo = config.build_algo()
    curve: list[dict] = []
    reached = False
    stage, stage_start = 0, 0
    try:
        while time.monotonic() - start < minutes * 60:
            result = algo.train()
            runners = result.get("env_runners", {})
            steps = int(
                runners.get("num_env_steps_sampled_lifetime")
                or result.get("num_env_steps_sampled_lifetime", 0)
            )
            means = {r.metric: float(runners.get(f"gf_{r.metric}", float("nan"))) for r in rules}
            reached = (
                stage == last
                and runners.get("num_episodes_lifetime", 0) >= window
                and all(r.passes(means[r.metric]) for r in rules)
            )
            returns = float(runners.get("episode_return_mean", float("nan")))
            curve.append(
                {
                    "wall_s": time.monotonic() - start,
                    "env_steps": steps,
                    "stage": stage,
                    "return": returns,
                    **means,
                }
            )
            console.log(f"rllib {job.name}: {curve[-1]}")
            if reached:
                break
            if stage < last and steps - stage_start >= job.stages[stage].env_steps:
                stage, stage_start = stage + 1, steps
                _push_stage(algo, env_config(job, scenes, stage))
                console.log(f"rllib {job.name}: stage {stage} ({scenes[stage].name}) at {steps}")
        evaluation = None
        if eval_episodes:
            evaluation = _evaluate(algo, job, scenes[stage], stage, eval_episodes)
    finally:
        algo.stop()
    return curve, reached, evaluation


def _push_stage(algo, cfg: dict) -> None:
    """Every remote env runner rebuilds its envs on ``cfg`` (their episodes start afresh)."""

    def switch(runner) -> None:
        runner.config.env_config.update(cfg)
        runner.make_env()

    algo.env_runner_group.foreach_env_runner(switch, local_env_runner=False)


def _evaluate(algo, job: Job, scene: Scene, stage: int, episodes: int) -> dict:
    """The module's mean action on ``scene``, ``episodes`` deterministic episodes, as
    ``bench/learning.py`` evaluates gaitforge's runs."""
    backend = job.stage_backend(stage)
    policy = RLlibMeanPolicy(algo.get_module())
    result = evaluate_policy(policy, scene, backend, episodes=episodes)  # type: ignore[arg-type]
    report = EvaluationReport(
        checkpoint=None,
        env_steps=None,
        scene=scene.name,
        backend=backend,
        seed=0,
        results={"deterministic": result},
    )
    out = report.to_dict()["results"]["deterministic"]
    out.pop("episodes", None)
    return out
