"""Can this body get going faster, or more safely, than its policy does? An open-loop start
searched for on top of a policy: offsets to its joint-target actions over the first seconds
from standing (``bench/start_offsets.py``: linear between knots, back to none at the last),
optimised with CMA-ES (the ``cma`` package, ``pip install -e .[bench]``) for the distance the
body covers by ``--horizon-s`` on deterministic episodes, less ``--fall-penalty-m`` for each
fall, the policy driving throughout. If some offsets reach speed much sooner than the policy
alone, the start is a learning problem; if none do, the body and its actuation are the limit.

Each generation logs the best and median distance; the end judges the policy with and
without the best offsets on ``--judge`` fresh whole episodes (seeds from 1000: falls, mean
speed, distance by 1.2, 2 and 4 s) and, with ``--out``, writes the offsets and figures
(``start-search.json``, which ``bench/start_distil.py`` reads) and the speed profiles
(``start-search.png``).

Usage: python bench/start_search.py [CHECKPOINT] [--scene run-2d+clock] [--knots-s 0.4 0.8
           1.2 1.6 2.0] [--seeds 0 1] [--horizon-s 5] [--fall-penalty-m 5] [--generations 40]
           [--sigma 0.1] [--cma-seed 1] [--judge 50] [--processes 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console

sys.path.insert(0, str(Path(__file__).parent))
from start_offsets import (
    distance_by,
    judge_episode,
    open_runner,
    open_worker,
    plot_speeds,
    summary,
    summary_table,
    worker_control_hz,
    worker_episode,
)

console = Console(width=160)


def score(args: tuple[np.ndarray | None, tuple[int, ...], float]) -> tuple[float, float, int]:
    """In a pool process, offsets over deterministic episodes of ``seeds`` cut at
    ``horizon_s``: (mean distance by the horizon (m), mean distance by 1.2 s (m), falls)."""
    values, seeds, horizon_s = args
    far, early, falls = [], [], 0
    for seed in seeds:
        distance, fell = worker_episode(values, seed, horizon_s)
        far.append(distance[-1])
        early.append(distance_by(distance, 1.2, worker_control_hz()))
        falls += fell
    return float(np.mean(far)), float(np.mean(early)), falls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", nargs="?", default="examples/policies/run-2d")
    parser.add_argument("--scene", default="run-2d+clock")
    parser.add_argument(
        "--knots-s",
        type=float,
        nargs="+",
        default=[0.4, 0.8, 1.2, 1.6, 2.0],
        help="s; offsets at 0 and at each knot but the last (0 there)",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="episodes searched on")
    parser.add_argument("--horizon-s", type=float, default=5.0)
    parser.add_argument("--fall-penalty-m", type=float, default=5.0)
    parser.add_argument("--generations", type=int, default=40)
    parser.add_argument("--sigma", type=float, default=0.1, help="in action units ([0, 1])")
    parser.add_argument("--cma-seed", type=int, default=1)
    parser.add_argument(
        "--range-rad",
        type=float,
        help="rad; the joint targets' span either "
        "side of their base instead of the scene's (the policy's actions "
        "rescaled to the same targets), so the offsets may reach further",
    )
    parser.add_argument("--judge", type=int, default=50, help="whole episodes, seeds from 1000")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    import cma  # the bench extra

    knots = (0.0, *args.knots_s)
    if any(b <= a for a, b in itertools.pairwise(knots)):
        raise SystemExit(f"--knots-s {args.knots_s}: ascending times above 0 are needed")
    _, runner, _ = open_runner(args.checkpoint, args.scene, args.range_rad)
    scene, n_act = runner.scene, len(runner.act_names)
    runner.close()
    es = cma.CMAEvolutionStrategy(
        np.zeros((len(knots) - 1) * n_act), args.sigma, {"seed": args.cma_seed, "verbose": -9}
    )
    seeds, history, started = tuple(args.seeds), [], time.monotonic()
    with mp.get_context("spawn").Pool(
        args.processes, open_worker, (args.checkpoint, args.scene, knots, args.range_rad)
    ) as pool:
        alone = pool.map(score, [(None, seeds, args.horizon_s)])[0]
        console.log(
            f"policy alone: {alone[0]:.2f} m by {args.horizon_s} s, {alone[1]:.2f} m by "
            f"1.2 s, {alone[2]} falls over seeds {list(seeds)}"
        )
        for generation in range(args.generations):
            candidates = es.ask()
            scores = pool.map(score, [(c, seeds, args.horizon_s) for c in candidates])
            es.tell(candidates, [-far + args.fall_penalty_m * falls for far, _, falls in scores])
            best = max(scores, key=lambda s: s[0] - args.fall_penalty_m * s[2])
            median = float(np.median([s[0] for s in scores]))
            history.append({"generation": generation, "best": best, "median_far": median})
            console.log(
                f"generation {generation}: best {best[0]:.2f} m by {args.horizon_s} s "
                f"({best[1]:.2f} m by 1.2 s, {best[2]} falls), median {median:.2f} m, "
                f"{time.monotonic() - started:.0f} s"
            )
        values = np.asarray(es.result.xbest).reshape(-1, n_act)
        judged = {
            label: pool.map(judge_episode, [(v, s) for s in range(1000, 1000 + args.judge)])
            for label, v in (("policy", None), ("policy + offsets", values))
        }
    summaries = {k: summary(runs, scene.control_hz, scene.episode_s) for k, runs in judged.items()}
    console.print(
        summary_table(f"{args.scene}: {args.judge} deterministic episodes (seeds 1000-)", summaries)
    )
    console.print(
        f"offsets (action units) at {knots[:-1]} s:\n{np.array2string(values, precision=3)}"
    )
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "start-search.json").write_text(
            json.dumps(
                {
                    "args": {
                        k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
                    },
                    "knots_s": knots,
                    "offsets": values.tolist(),
                    "history": history,
                    "summaries": summaries,
                    "distances": {
                        k: [[round(x, 3) for x in d] for d, _ in runs] for k, runs in judged.items()
                    },
                },
                indent=None,  # one line: the distances are long
            )
        )
        plot_speeds(
            judged,
            scene.control_hz,
            f"{args.scene}: the policy with and without a searched start",
            args.out / "start-search.png",
        )
        console.log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
