"""Reflex controller candidates scored per minute: in this process against 1, 2, ... Ray
actors, side by side in one run.

Usage: python bench/cmaes_speed.py [--actors 1 2] [--candidates 64] [--episodes 2]
    [--scene reflex-walk-3d] [--backend mujoco] [--seconds 10]

Each arm scores the same candidates (the default parameters with a seeded spread of 0.05
of each range, as a CMA-ES generation at that sigma spreads them) over the same reset seeds,
episodes of at most ``--seconds`` that end where the body falls, as in a search (the
simulated time is counted from the env steps scored). The in-process arm is one
``RolloutWorker``; the others a ``WorkerPool`` of that many actors, timed after its actors
are up (their start-up, a few seconds, is paid once per run). The table gives candidates a
minute, simulated seconds per wall-clock second, and the ratio to the in-process arm.
"""

from __future__ import annotations

import argparse
import functools
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from gaitforge.workers.gait_measure import GaitMeasure
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.io_names import action_names
from gaitforge.workers.scenes.reflex_parameters import DEFAULTS, LOWER, UPPER
from rich.console import Console
from rich.table import Table

console = Console()


def candidates(count: int, seed: int = 0) -> list[np.ndarray]:
    """``count`` parameter vectors around the defaults (0.05 of each range), in bounds."""
    rng = np.random.default_rng(seed)
    spread = 0.05 * (UPPER - LOWER)
    return [
        np.clip(DEFAULTS + spread * rng.standard_normal(DEFAULTS.size), LOWER, UPPER)
        for _ in range(count)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--candidates", type=int, default=64)
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--scene", default="reflex-walk-3d")
    parser.add_argument("--backend", default="mujoco")
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    scene = load_scene(args.scene, {"episode_s": args.seconds}, backend=args.backend).resolved()
    policy = functools.partial(UniformExcitationPolicy, len(action_names(scene, args.backend)))
    work, seeds, measure = candidates(args.candidates), list(range(args.episodes)), GaitMeasure()
    rows: list[tuple[str, float, float]] = []
    """(arm, wall s, simulated s)"""

    def simulated(scores: list) -> float:
        return sum(s.env_steps for s in scores) / scene.control_hz

    local = RolloutWorker(scene, policy, backend=args.backend, num_envs=1)
    start = time.perf_counter()
    scores = local.score_candidates(work, seeds, measure)
    rows.append(("in-process", time.perf_counter() - start, simulated(scores)))

    import ray
    from gaitforge.workers.pool import WorkerPool

    ray.init(include_dashboard=False, logging_level="ERROR")
    for actors in args.actors:
        pool = WorkerPool(
            scene,
            policy,
            backend=args.backend,
            num_workers=actors,
            envs_per_worker=1,
            queue_depth=0,
        )
        pool.score_candidates(work[:actors], [0], measure)  # the actors up and warm
        start = time.perf_counter()
        scores = pool.score_candidates(work, seeds, measure)
        rows.append((f"{actors} actor(s)", time.perf_counter() - start, simulated(scores)))
        pool.close()
    ray.shutdown()

    table = Table(
        "scorer",
        "candidates/min",
        "simulated s per s",
        "x in-process",
        title=(
            f"{args.scene} on {args.backend}: {args.candidates} candidates x {args.episodes} "
            f"episodes of at most {args.seconds:g} s ({os.cpu_count()} CPUs)"
        ),
    )
    base = rows[0][1]
    for name, wall, sim_s in rows:
        table.add_row(
            name, f"{60 * args.candidates / wall:.0f}", f"{sim_s / wall:.1f}", f"{base / wall:.2f}"
        )
    console.print(table)


if __name__ == "__main__":
    main()
