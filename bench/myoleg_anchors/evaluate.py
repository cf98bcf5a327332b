"""Evaluate an anchor run's policy on MyoSuite's ``myoLegWalk-v0`` by two measures.

    python bench/myoleg_anchors/evaluate.py DIR [--episodes 10] [--seed 1000]
        [--reset-type random|init] [--min-pelvis-height 0.6] [--out FILE]

``DIR`` is a run folder written by ``sb3_walk.py`` or ``deprl_walk.py``; its newest checkpoint
is evaluated for N deterministic episodes (SB3: the Gaussian's mean; DEP-RL: the MPO actor's
mean, as deprl's own ``test_step``, without DEP) on the plain registered env. Each episode
runs until MyoSuite ends it or for 10 s (1000 steps of 0.01 s), whichever comes first.

MyoSuite's measure: the share of episodes "solved" as MyoSuite's own ``evaluate_success``
counts it: an episode is solved when its per-step ``solved`` flag (planar COM velocity within
0.5 m/s of the 1.2 m/s target, not fallen) is set on more than 5 steps.

gaitforge's measure: the mean forward speed, m/s, of the pelvis along the rewarded direction
(world -y) over each episode (displacement from reset to the last step over the episode's
simulated time), and the share of episodes that fall within 10 s: MyoSuite ends the episode
early (COM below 0.8 m, torso rotated, or a simulator instability) or the pelvis drops below
``--min-pelvis-height`` (0.6 m, gaitforge's walk-3d threshold).

``--reset-type random`` (the default here; DEP-RL's training setting) starts each episode
from one of two keyframes with small joint noise, so episodes differ; ``init`` is the
registered env's default, a fixed start from which deterministic episodes are identical.

Prints a table and writes JSON (default ``DIR/eval.json``).
"""

from __future__ import annotations

import argparse
import logging
import pickle
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from common import ENV_ID, EVAL_FILE, RUN_FILE, STATE_FILE, read_json, write_json

log = logging.getLogger(__name__)

#: A policy: observation (MyoSuite's vector) -> muscle activations in [0, 1] (1).
Policy = Callable[[np.ndarray], np.ndarray]

#: gaitforge's walk-3d fall threshold on the pelvis height, m.
MIN_PELVIS_HEIGHT_M = 0.6
#: Longest episode evaluated, s.
EPISODE_LIMIT_S = 10.0
#: MyoSuite's ``evaluate_success`` default: solved on more than this many steps.
MYOSUITE_SUCCESSFUL_STEPS = 5


@dataclass(frozen=True)
class EpisodeResult:
    """One evaluated episode.

    Attributes:
        seed: the reset seed.
        steps: control steps taken (0.01 s each).
        time_s: simulated time, s.
        distance_m: pelvis displacement along -y from reset to the last step, m.
        speed_m_s: distance_m / time_s, m/s.
        ended_early: MyoSuite terminated the episode before 10 s.
        min_pelvis_height_m: lowest pelvis height seen, m.
        fell: ended early, or the pelvis went below the fall threshold.
        solved_steps: steps whose MyoSuite ``solved`` flag was set.
        myosuite_solved: solved as MyoSuite counts it (more than 5 solved steps).
        episode_return: sum of MyoSuite's reward (1).
    """

    seed: int
    steps: int
    time_s: float
    distance_m: float
    speed_m_s: float
    ended_early: bool
    min_pelvis_height_m: float
    fell: bool
    solved_steps: int
    myosuite_solved: bool
    episode_return: float


def _sb3_policy(run_dir: Path, state: dict[str, Any]) -> Policy:
    """The SB3 run's newest checkpoint as a deterministic policy."""
    from stable_baselines3 import PPO

    model = PPO.load(run_dir / state["checkpoint"], device="cpu")
    normalizer = None
    if state.get("vecnormalize"):
        with (run_dir / state["vecnormalize"]).open("rb") as f:
            normalizer = pickle.load(f)  # a VecNormalize saved by this run
        normalizer.training = False

    def policy(obs: np.ndarray) -> np.ndarray:
        x = obs[None].astype(np.float32)
        if normalizer is not None:
            x = normalizer.normalize_obs(x)
        action, _ = model.predict(x, deterministic=True)
        return (np.clip(action[0], -1.0, 1.0) + 1.0) / 2.0  # [-1, 1] -> [0, 1], as trained

    return policy


def _deprl_policy(run_dir: Path, state: dict[str, Any], obs_dim: int, act_dim: int) -> Policy:
    """The DEP-RL run's newest checkpoint as a deterministic policy (weights loaded strictly)."""
    import adapters
    import gymnasium as gym
    import torch
    import yaml

    adapters.install()
    import deprl

    experiment = run_dir / state["experiment_dir"]
    config = yaml.safe_load((experiment / "config.yaml").read_text())
    agent = eval(config["tonic"]["agent"], {"deprl": deprl})  # the config's own agent string
    agent.set_params(**config.get("mpo_args", {}))
    agent.initialize(
        observation_space=gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32),
        action_space=gym.spaces.Box(-1.0, 1.0, (act_dim,), np.float32),
        seed=0,
    )
    weights = torch.load(
        run_dir / (state["checkpoint"] + ".pt"), map_location="cpu", weights_only=True
    )
    agent.model.load_state_dict(weights)

    def policy(obs: np.ndarray) -> np.ndarray:
        action = agent.test_step(obs[None].astype(np.float32), steps=0)
        return adapters.myosuite2_activation(action[0])

    return policy


def load_policy(run_dir: Path, obs_dim: int, act_dim: int) -> tuple[Policy, dict[str, Any]]:
    """The newest checkpoint of the run in ``run_dir`` and a description of it.

    Args:
        run_dir: the run folder.
        obs_dim: size of MyoSuite's observation vector.
        act_dim: number of muscles (actions).
    """
    run = read_json(run_dir / RUN_FILE)
    state_path = run_dir / STATE_FILE
    if not state_path.exists():
        raise SystemExit(f"{run_dir}: no checkpoint yet ({STATE_FILE} missing)")
    state = read_json(state_path)
    if run["runner"] == "sb3":
        policy = _sb3_policy(run_dir, state)
    elif run["runner"] == "deprl":
        policy = _deprl_policy(run_dir, state, obs_dim, act_dim)
    else:
        raise SystemExit(f"{run_dir}: unknown runner {run['runner']!r}")
    about = {
        "runner": run["runner"],
        "checkpoint": state["checkpoint"],
        "env_steps": state.get("env_steps"),
        "train_seconds": state.get("train_seconds"),
    }
    return policy, about


def run_episodes(
    policy: Policy,
    episodes: int,
    seed: int,
    reset_type: str,
    min_pelvis_height: float = MIN_PELVIS_HEIGHT_M,
) -> tuple[list[EpisodeResult], float]:
    """Roll ``policy`` out on ``myoLegWalk-v0``.

    Args:
        policy: observation -> activations in [0, 1].
        episodes: how many episodes.
        seed: reset seed of the first episode; episode i uses ``seed + i``.
        reset_type: the env's ``reset_type`` ("random" or "init").
        min_pelvis_height: fall threshold on the pelvis height, m.

    Returns:
        the episodes, and MyoSuite's ``evaluate_success`` over them (percent).
    """
    from myosuite.utils import gym

    env = gym.make(ENV_ID, reset_type=reset_type)
    base = env.unwrapped
    pelvis = base.model.body("pelvis").id
    max_steps = round(EPISODE_LIMIT_S / base.dt)
    results: list[EpisodeResult] = []
    paths: list[dict[str, Any]] = []
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        y0 = float(base.data.xpos[pelvis][1])
        min_z = float(base.data.xpos[pelvis][2])
        solved: list[bool] = []
        total = 0.0
        terminated = truncated = False
        steps = 0
        while steps < max_steps and not (terminated or truncated):
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            steps += 1
            total += float(reward)
            solved.append(bool(info.get("solved", False)))
            min_z = min(min_z, float(base.data.xpos[pelvis][2]))
        time_s = steps * base.dt
        distance = -(float(base.data.xpos[pelvis][1]) - y0)
        ended_early = bool(terminated) and steps < max_steps
        solved_flags = np.asarray(solved, dtype=bool)
        paths.append({"env_infos": {"solved": solved_flags}})
        results.append(
            EpisodeResult(
                seed=seed + i,
                steps=steps,
                time_s=time_s,
                distance_m=distance,
                speed_m_s=distance / time_s if time_s > 0 else 0.0,
                ended_early=ended_early,
                min_pelvis_height_m=min_z,
                fell=ended_early or min_z < min_pelvis_height,
                solved_steps=int(solved_flags.sum()),
                myosuite_solved=int(solved_flags.sum()) > MYOSUITE_SUCCESSFUL_STEPS,
                episode_return=total,
            )
        )
    success_pct = float(base.evaluate_success(paths, successful_steps=MYOSUITE_SUCCESSFUL_STEPS))
    env.close()
    return results, success_pct


def summarize(results: list[EpisodeResult], success_pct: float) -> dict[str, float]:
    """Means over the episodes (shares in [0, 1])."""
    n = len(results)
    return {
        "episodes": n,
        "myosuite_solved_share": success_pct / 100.0,
        "mean_speed_m_s": float(np.mean([r.speed_m_s for r in results])),
        "fall_share_10s": float(np.mean([r.fell for r in results])),
        "mean_distance_m": float(np.mean([r.distance_m for r in results])),
        "mean_time_s": float(np.mean([r.time_s for r in results])),
        "mean_return": float(np.mean([r.episode_return for r in results])),
        "mean_solved_steps": float(np.mean([r.solved_steps for r in results])),
    }


def evaluate_run(
    run_dir: Path,
    episodes: int = 10,
    seed: int = 1000,
    reset_type: str = "random",
    min_pelvis_height: float = MIN_PELVIS_HEIGHT_M,
    out: Path | None = None,
) -> dict[str, Any]:
    """Evaluate the run in ``run_dir`` and write the JSON (default ``run_dir/eval.json``)."""
    from myosuite.utils import gym

    probe = gym.make(ENV_ID)
    obs_dim = int(probe.observation_space.shape[0])
    act_dim = int(probe.action_space.shape[0])
    probe.close()
    policy, about = load_policy(run_dir, obs_dim, act_dim)
    results, success_pct = run_episodes(policy, episodes, seed, reset_type, min_pelvis_height)
    report = {
        **about,
        "env_id": ENV_ID,
        "reset_type": reset_type,
        "seed": seed,
        "min_pelvis_height_m": min_pelvis_height,
        "episode_limit_s": EPISODE_LIMIT_S,
        "summary": summarize(results, success_pct),
        "episodes": [asdict(r) for r in results],
    }
    write_json(out or run_dir / EVAL_FILE, report)
    return report


def format_table(report: dict[str, Any]) -> str:
    """A small text table of the episodes and their means."""
    head = (
        f"{'episode':>8} {'steps':>6} {'time s':>7} {'speed -y m/s':>13} {'fell':>5} "
        f"{'min pelvis m':>13} {'solved steps':>13} {'return':>9}"
    )
    lines = [
        f"{report['runner']} checkpoint {report['checkpoint']} "
        f"({report['env_steps']} env steps, {report['train_seconds'] or 0:.0f} s training), "
        f"reset_type={report['reset_type']}",
        head,
    ]
    for r in report["episodes"]:
        lines.append(
            f"{r['seed']:>8} {r['steps']:>6} {r['time_s']:>7.2f} {r['speed_m_s']:>13.3f} "
            f"{'yes' if r['fell'] else 'no':>5} {r['min_pelvis_height_m']:>13.3f} "
            f"{r['solved_steps']:>13} {r['episode_return']:>9.1f}"
        )
    s = report["summary"]
    lines.append(
        f"MyoSuite solved share {s['myosuite_solved_share']:.2f} | "
        f"mean speed along -y {s['mean_speed_m_s']:.3f} m/s | "
        f"fall share within {report['episode_limit_s']:.0f} s {s['fall_share_10s']:.2f} | "
        f"mean return {s['mean_return']:.1f} over {s['episodes']} episodes"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Command line: see the module docstring."""
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("run_dir", type=Path, help="run folder (sb3_walk.py or deprl_walk.py --out)")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=1000, help="reset seed of the first episode")
    p.add_argument("--reset-type", choices=("random", "init"), default="random")
    p.add_argument("--min-pelvis-height", type=float, default=MIN_PELVIS_HEIGHT_M, help="m")
    p.add_argument("--out", type=Path, default=None, help="JSON path (default DIR/eval.json)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    report = evaluate_run(
        args.run_dir,
        episodes=args.episodes,
        seed=args.seed,
        reset_type=args.reset_type,
        min_pelvis_height=args.min_pelvis_height,
        out=args.out,
    )
    print(format_table(report))
    print(f"wrote {args.out or args.run_dir / EVAL_FILE}")


if __name__ == "__main__":
    sys.exit(main())
