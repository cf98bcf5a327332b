"""Judge tuned reflex controllers as the 3-D targets ask: deterministic episodes with the
scene's reset noise, on seeds no search tuned on, the controller alone (no residual).

Usage: python bench/reflex_judge.py TUNED.yaml [MORE.yaml ...] [--episodes 100]
    [--first-seed 100000] [--backend mujoco] [--set PATH=VALUE ...] [--json out.json]

Each scene file is a search's ``tuned.yaml`` (``gaitforge tune``, or a job's
``<run>/cmaes/stage-<i>/tuned.yaml``). Episode i resets with seed ``first-seed + i`` (the
searches draw theirs from ``seed * 1000003 + generation * episodes``, far below 100000 for
any search this project runs). The table gives, for each file side by side: the share of
episodes that fell, the median speed (distance over the full episode, so that a fall stops
the clock), the median time alive and the env steps simulated. ``--set`` changes every
scene alike, for example ``--set 'pushes={force_n: [60, 120]}'`` to judge them under pushes.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.gait_measure import GaitMeasure, score_candidate
from gaitforge.workers.overrides import parse_assignments
from gaitforge.workers.scenes import load_scene
from rich.console import Console
from rich.table import Table

console = Console()


def judge(
    path: Path, episodes: int, first_seed: int, backend: str, fields: dict | None = None
) -> dict[str, float]:
    """One tuned scene's figures over ``episodes`` episodes (see the module docstring),
    with ``fields`` (dotted path -> value) set."""
    scene = load_scene(path, fields, backend=backend).resolved()
    env = MuscleEnv(scene, backend)
    scores = [
        score_candidate(env, env.gait.parameters, [first_seed + i], GaitMeasure())
        for i in range(episodes)
    ]
    return {
        "falls": float(np.mean([s.falls for s in scores])),
        "speed_mps": float(np.median([s.speed for s in scores])),
        "alive_s": float(np.median([s.alive for s in scores])) * scene.episode_s,
        "env_steps": int(sum(s.env_steps for s in scores)),
        "episodes": episodes,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tuned", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--first-seed", type=int, default=100_000)
    parser.add_argument("--backend", choices=["mujoco", "opensim"], default="mujoco")
    parser.add_argument("--set", action="append", default=[], metavar="PATH=VALUE")
    parser.add_argument("--json", type=Path, help="write the figures here too")
    args = parser.parse_args()
    fields = parse_assignments(args.set)
    results = {
        str(p): judge(p, args.episodes, args.first_seed, args.backend, fields) for p in args.tuned
    }
    table = Table(title=f"{args.episodes} episodes from seed {args.first_seed} on {args.backend}")
    for column in ("tuned scene", "falls", "speed m/s (median)", "alive s (median)", "env steps"):
        table.add_column(column)
    for path, r in results.items():
        table.add_row(
            path,
            f"{100 * r['falls']:.0f} %",
            f"{r['speed_mps']:.2f}",
            f"{r['alive_s']:.2f}",
            str(r["env_steps"]),
        )
    console.print(table)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
