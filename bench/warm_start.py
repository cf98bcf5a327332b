"""A/B: PPO on an imitation scene with and without the warm start from recorded excitations
(a stage's ``warm_start``, ``learner.clone_excitations``), same seeds, same wall clock.

Usage: python bench/warm_start.py [--job examples/imitate-walk-2d.yaml] [--seeds 0 1 2]
                                  [--minutes 3] [--eval-episodes 20] [--workers W]
                                  [--out bench/results/warm_start]

For each seed, two runs of the job's first stage, one after the other (cold, then warm): the
job as it is without any warm start ("cold") and with ``warm_start: {excitations: <the
motion the scene imitates>}`` at its defaults ("warm"). Each trains for ``--minutes`` of wall
clock from the trainer's start (the warm start's rollouts and fit count in it), then its
newest checkpoint is evaluated deterministically over ``--eval-episodes`` episodes
(``learner.evaluate``): tracking error (rad), share of episodes that kept the gait, episode
length (s), fall rate, mean speed (m/s), return. The table gives each run and the median
per arm; ``warm_start.json`` holds everything. Without ``--job`` (or when the file is
missing) the job is ``examples/walk-2d.yaml``'s settings on scene ``imitate-walk-2d``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import ray
from gaitforge.learner.evaluate import evaluate_checkpoint
from gaitforge.learner.job import Job, load_job, resolve_scenes
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.ray_start import start_ray
from rich.console import Console
from rich.table import Table

console = Console()
ROOT = Path(__file__).parents[1]
DEFAULT_JOB = ROOT / "examples" / "imitate-walk-2d.yaml"
FIGURES = ("tracking_rad", "kept_gait", "length_s", "fall_rate", "speed", "return")


def base_job(path: Path) -> tuple[Job, Path]:
    """The job to compare on (its first stage only), and the folder its paths are relative to."""
    if path.exists():
        job, _ = load_job(path)
        return job, path.parent
    job, _ = load_job(ROOT / "examples" / "walk-2d.yaml")
    raw = job.model_dump()
    raw["name"] = "imitate-walk-2d"
    raw["stages"][0].update(scene="imitate-walk-2d", promote=[])
    return Job.model_validate(raw), ROOT / "examples"


def arm(job: Job, seed: int, workers: int, warm: bool) -> Job:
    """The job's first stage alone, seeded, with (``warm``) or without a warm start."""
    raw = job.model_dump()
    raw["seed"] = seed
    raw["workers"]["num_workers"] = workers
    stage = raw["stages"][0]
    stage["env_steps"] = max(stage["env_steps"], 10**9)  # the wall clock ends it
    stage["promote"] = []
    stage["warm_start"] = None
    raw["stages"] = [stage]
    if warm:
        scenes = resolve_scenes(Job.model_validate(raw))
        stage["warm_start"] = {"excitations": scenes[0].task.imitate.motion}
    return Job.model_validate(raw)


def run(job: Job, base: Path, minutes: float, out: Path, episodes: int) -> dict:
    """Train ``job`` for ``minutes`` of wall clock in ``out``; evaluate its newest checkpoint."""
    start = time.monotonic()
    scenes = resolve_scenes(job, base=base)
    trainer = Trainer(job, out, scenes, tensorboard=False)
    history = trainer.run(max_seconds=minutes * 60)
    wall = time.monotonic() - start
    report = evaluate_checkpoint(out, episodes=episodes, modes=("deterministic",))
    r = report.results["deterministic"]
    last = history[-1] if history else {}
    full = report.to_dict()["results"]["deterministic"]
    figures = {
        "tracking_rad": r.tracking_error_rad.mean if r.tracking_error_rad else None,
        "kept_gait": r.kept_gait_rate.value if r.kept_gait_rate else None,
        "length_s": r.time_s.mean,
        "fall_rate": r.fall_rate.value,
        "speed": r.mean_speed_m_s.mean,
        "return": r.return_.mean,
    }
    console.log(f"{out.name}: {trainer.env_steps:,} env steps in {wall:.0f} s; {figures}")
    return {
        "wall_s": wall,
        "env_steps": trainer.env_steps,
        "iterations": trainer.iteration,
        "train_last": {k: last.get(k) for k in ("return", "length", "fall_rate", "survival")},
        "evaluation": figures,
        "evaluation_full": {k: v for k, v in full.items() if k != "episodes"},
    }


def median(runs: list[dict], key: str) -> float | None:
    values = [r["evaluation"][key] for r in runs if r["evaluation"][key] is not None]
    return statistics.median(values) if values else None


def render(results: dict) -> Table:
    out = Table(title=f"Warm start A/B, {results['minutes']} min each, {os.cpu_count()} CPUs")
    for col in ("arm", "seed", "env steps", *FIGURES):
        out.add_column(col)

    def cells(values: dict) -> list[str]:
        return ["-" if values.get(k) is None else f"{values[k]:.3f}" for k in FIGURES]

    for name in ("cold", "warm"):
        for seed, r in results["runs"][name].items():
            out.add_row(name, str(seed), f"{r['env_steps']:,}", *cells(r["evaluation"]))
        runs = list(results["runs"][name].values())
        out.add_row(f"{name} median", "", "", *cells({k: median(runs, k) for k in FIGURES}))
    return out


def markdown(results: dict) -> str:
    """The medians as a Markdown table (for the README)."""
    lines = ["| arm | " + " | ".join(FIGURES) + " |", "|---" * (len(FIGURES) + 1) + "|"]
    for name in ("cold", "warm"):
        runs = list(results["runs"][name].values())
        values = [median(runs, k) for k in FIGURES]
        cells = ["-" if v is None else f"{v:.3f}" for v in values]
        lines.append(f"| {name} (median of {len(runs)}) | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--job", type=Path, default=DEFAULT_JOB)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", type=Path, default=Path("bench/results/warm_start"))
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("gaitforge.learner.transitions").setLevel(logging.INFO)
    start_ray()
    workers = args.workers or max(1, int(ray.cluster_resources()["CPU"]) - 1)
    job, base = base_job(args.job)
    results: dict = {
        "job": job.name,
        "minutes": args.minutes,
        "workers": workers,
        "eval_episodes": args.eval_episodes,
        "runs": {"cold": {}, "warm": {}},
    }
    for seed in args.seeds:  # interleaved, so that a change in the machine's load hits both
        for name in ("cold", "warm"):
            out = args.out / "runs" / f"{name}-seed-{seed}"
            if out.exists():
                shutil.rmtree(out)
            results["runs"][name][seed] = run(
                arm(job, seed, workers, name == "warm"), base, args.minutes, out,
                args.eval_episodes,
            )  # fmt: skip
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / "warm_start.json").write_text(json.dumps(results, indent=1))
    console.print(render(results))
    console.print(markdown(results))
    console.print(f"written: {args.out / 'warm_start.json'}")


if __name__ == "__main__":
    main()
