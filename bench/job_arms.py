"""Arms of a learning A/B: one job file, changed per arm, trained on each seed one run after
another (``gaitforge train``), each end network judged again on fresh deterministic episodes
(``gaitforge evaluate``, seeds 0..N-1 unless ``--judge-seed``, not the 1,000,000 + i the
runs watched), and a table of falls and mean speed per arm and seed with the median over
seeds.

Usage:
    python bench/job_arms.py JOB.yaml --out DIR --arm NAME [KEY=VALUE ...] [--arm ...]
        [--seeds 0 1 2] [--scene run-2d+clock | stage] [--episodes 200] [--judge-seed 0]
        [--side-by-side N] [--train-minutes M]

An arm is a name and dotted overrides of the job file, values read as YAML:
``--arm gamma-0.99 ppo.gamma=0.99``, ``--arm short stages.0.scene=short.yaml``; an arm with
no override is the job as it is (the control). Relative paths in the job and in the overrides
(``init_from``, a stage's scene or evaluation scene given as a YAML file) are taken from the
job file's directory. ``--scene stage`` judges each run on its last stage's own scene (arms
that train on different scenes with the same falls and speed, such as run-2d+clock variants
with other clocks); ``--judge-seed`` is the first episode seed judged. Writes
``DIR/ARM/seed-S.yaml``, ``.log``, the run under ``DIR/ARM/seed-S/``, its judgement
``DIR/ARM/seed-S.json`` and ``.txt``, and ``DIR/arms.json``; a seed already judged is not run
again, so a stopped A/B goes on where it was.

On a machine with many cores, ``--side-by-side N`` trains and judges up to N runs at once
(each its own ``gaitforge train``; give each run its share of the cores with
``workers.num_workers``, 0 for in-process rollouts, and torch one thread: the runs start with
``OMP_NUM_THREADS=1`` unless it is set), and ``--train-minutes M`` ends each training after M
minutes of wall clock (``gaitforge train --max-minutes``), the stage's budget otherwise.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import yaml
from gaitforge.learner.job import read_job_fields
from gaitforge.workers.overrides import parse_assignments
from gaitforge.workers.spec_io import SpecError
from rich.console import Console
from rich.logging import RichHandler
from rich.table import Table

logger = logging.getLogger("job_arms")


def parse_arm(words: list[str]) -> tuple[str, dict[str, Any]]:
    """``[NAME, KEY=VALUE, ...]`` -> (name, {dotted key: value read as YAML})."""
    name, *pairs = words
    try:
        return name, parse_assignments(pairs, where=f"--arm {name}")
    except SpecError as exc:
        raise SystemExit(str(exc)) from None


def _absolute(ref: Any, base: Path) -> Any:
    """A relative path (a checkpoint directory, or a YAML file) made absolute from ``base``;
    anything else (a catalogue scene's name, None) as it is."""
    if not isinstance(ref, str) or Path(ref).is_absolute():
        return ref
    candidate = base / ref
    return str(candidate.resolve()) if candidate.exists() else ref


def arm_job(template: Path, seed: int, overrides: dict[str, Any]) -> dict[str, Any]:
    """The job file's data (its ``extends`` followed) with the seed and the arm's overrides
    set (dotted paths, as ``gaitforge train --set``) and its relative paths made absolute (so
    the filled job can live anywhere)."""
    data = read_job_fields(template, {**overrides, "seed": seed})
    base = template.parent
    data["init_from"] = _absolute(data.get("init_from"), base)
    for stage in data.get("stages", []):
        stage["scene"] = _absolute(stage.get("scene"), base)
        if isinstance(stage.get("evaluate"), dict) and "scene" in stage["evaluate"]:
            stage["evaluate"]["scene"] = _absolute(stage["evaluate"]["scene"], base)
    return data


def judged(json_path: Path) -> dict[str, float]:
    """Falls (fraction) and mean speed (m/s) of a ``gaitforge evaluate --json-out`` file's
    deterministic mode."""
    report = json.loads(json_path.read_text())
    mode = report["results"]["deterministic"]
    return {"fall_rate": mode["fall_rate"]["value"], "speed": mode["mean_speed_m_s"]["mean"]}


def judging_scene(job: dict[str, Any], scene: str) -> str:
    """``scene``, or for ``stage`` the job's last stage's scene (a name or a file path)."""
    return str(job["stages"][-1]["scene"]) if scene == "stage" else scene


def run_seed(
    job: dict[str, Any],
    where: Path,
    scene: str,
    episodes: int,
    train_minutes: float | None = None,
    judge_seed: int = 0,
) -> dict[str, float]:
    """Train ``job`` into ``where`` (a run directory) unless judged already, for at most
    ``train_minutes`` of wall clock if given; judge its end network on ``episodes`` episodes of
    ``scene`` (``stage``: the job's last stage's scene), seeds ``judge_seed`` on."""
    scene = judging_scene(job, scene)
    verdict = where.with_suffix(".json")
    if not verdict.exists():
        job_file = where.with_suffix(".yaml")
        job_file.write_text(yaml.safe_dump(job, sort_keys=False))
        logger.info("training %s", where)
        limit = [] if train_minutes is None else ["--max-minutes", str(train_minutes)]
        with where.with_suffix(".log").open("w") as log:
            subprocess.run(
                [
                    "gaitforge",
                    "train",
                    str(job_file),
                    "--run-dir",
                    str(where),
                    "--log-every",
                    "30",
                    *limit,
                ],
                stdout=log,
                stderr=subprocess.STDOUT,
                check=True,
            )
        logger.info("judging %s on %d episodes of %s", where, episodes, scene)
        with where.with_suffix(".txt").open("w") as table:
            subprocess.run(
                [
                    "gaitforge",
                    "evaluate",
                    str(where),
                    "--scene",
                    scene,
                    "--episodes",
                    str(episodes),
                    "--seed",
                    str(judge_seed),
                    "--json-out",
                    str(verdict),
                ],
                stdout=table,
                stderr=subprocess.STDOUT,
                check=True,
            )
    return judged(verdict)


def summary_table(results: dict[str, dict[int, dict[str, float]]], seeds: list[int]) -> Table:
    table = Table(title="falls and mean speed of the end networks (deterministic)")
    table.add_column("arm")
    for seed in seeds:
        table.add_column(f"seed {seed}", justify="right")
    table.add_column("median", justify="right")
    for arm, by_seed in results.items():
        cells = [f"{100 * r['fall_rate']:.0f} % at {r['speed']:.2f}" for r in by_seed.values()]
        falls = statistics.median(r["fall_rate"] for r in by_seed.values())
        speed = statistics.median(r["speed"] for r in by_seed.values())
        table.add_row(arm, *cells, f"{100 * falls:.0f} % at {speed:.2f} m/s")
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("job", type=Path, help="the job file every arm changes")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--arm",
        nargs="+",
        action="append",
        required=True,
        metavar="WORD",
        help="an arm: NAME [KEY=VALUE ...]",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument(
        "--scene",
        default="run-2d+clock",
        help="the scene judged on (stage: each run's last stage's)",
    )
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--judge-seed", type=int, default=0, help="the first episode seed judged")
    parser.add_argument(
        "--side-by-side",
        type=int,
        default=1,
        metavar="N",
        help="train and judge up to N runs at once",
    )
    parser.add_argument(
        "--train-minutes",
        type=float,
        default=None,
        metavar="M",
        help="end each training after M minutes (default: its budget)",
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s", handlers=[RichHandler()])
    if not args.job.is_file():
        raise SystemExit(f"{args.job}: no such job file")
    if args.side_by_side < 1:
        raise SystemExit(f"--side-by-side: {args.side_by_side} is not a number of runs >= 1")
    if args.train_minutes is not None and args.train_minutes <= 0:
        raise SystemExit(f"--train-minutes: {args.train_minutes} is not a positive duration")
    if args.side_by_side > 1:
        os.environ.setdefault("OMP_NUM_THREADS", "1")
    arms = dict(parse_arm(words) for words in args.arm)
    # seed by seed, so a stopped A/B has every arm on the first seeds
    runs = [(arm, seed) for seed in args.seeds for arm in arms]

    def run(arm: str, seed: int) -> dict[str, float]:
        where = args.out.resolve() / arm / f"seed-{seed}"
        where.parent.mkdir(parents=True, exist_ok=True)
        job = arm_job(args.job.resolve(), seed, arms[arm])
        verdict = run_seed(
            job, where, args.scene, args.episodes, args.train_minutes, args.judge_seed
        )
        logger.info("%s seed %d: %s", arm, seed, verdict)
        return verdict

    with ThreadPoolExecutor(max_workers=args.side_by_side) as pool:
        verdicts = list(pool.map(run, *zip(*runs, strict=True)))
    results: dict[str, dict[int, dict[str, float]]] = {arm: {} for arm in arms}
    for (arm, seed), verdict in zip(runs, verdicts, strict=True):
        results[arm][seed] = verdict
    (args.out / "arms.json").write_text(
        json.dumps(
            {
                "job": str(args.job),
                "scene": args.scene,
                "episodes": args.episodes,
                "judge_seed": args.judge_seed,
                "train_minutes": args.train_minutes,
                "arms": {arm: {"overrides": arms[arm], "seeds": results[arm]} for arm in arms},
            },
            indent=2,
        )
    )
    Console(width=160).print(summary_table(results, args.seeds))


if __name__ == "__main__":
    main()
