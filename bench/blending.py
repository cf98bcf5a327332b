"""Policy blending against behavioural cloning and training from scratch, on one stage
transition at equal env steps, over several seeds.

Usage: python bench/blending.py [--seeds 3] [--from-steps N] [--to-steps M]
                                [--from-scene S] [--to-scene S] [--workers W] [--out DIR]
       python bench/blending.py --job examples/obstacles-2d.yaml --to-steps M [--big 256 256]
                                [--transitions blend distil scratch blend-cloned continue]

Per seed, stage 0 trains a small network (``--small``, default 32x32) on ``--from-scene``
for ``--from-steps`` env steps, once; its final checkpoint is then copied three times, and
stage 1 goes on from it on ``--to-scene`` with a bigger network (``--big``, 128x128) built
by each transition for ``--to-steps`` env steps (warm-up rollouts included):

- blend:   pi_new trained in blend with the frozen pi_old, alpha ramped 0 -> 1 over half
           of the stage (critic fitted to pi_old's returns first);
- distil:  pi_new's actor cloned from pi_old's actions and its critic fitted, then PPO;
- scratch: a fresh pi_new;
- blend-cloned (on request): blend, with pi_new's actor first cloned from pi_old as for
           distil (``blend.clone_actor``).

With ``--job FILE`` the transition is a real one of the curriculum: the job file's first
stage starts from its ``init_from`` checkpoint (e.g. ``examples/obstacles-2d.yaml``: the
shipped runner onto obstacles-2d+clock), and each transition grows ``--big`` from it there
for ``--to-steps`` env steps with the job's own PPO and worker settings (no stage 0 is
trained); ``--transitions`` may add ``continue`` (the checkpoint's network, not grown) as a
baseline.

Reported per transition: the training return over the stage's last 100 episodes and a
deterministic evaluation (20 seeded episodes; ``--eval-episodes``) of the final policy (its
return, falls and speed), mean and spread (std)
over seeds, with the return right after the switch (first iteration) to show the dip that
blending avoids. The default transition is elbow-reach from a narrow band of targets to the
full range (fast enough for this 2-core machine); ``--from-scene stand-2d --to-scene
walk-2d`` is the locomotion one (hours on 2 cores). Writes ``blending.json`` and a learning
curve plot ``blending.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import torch
import yaml
from gaitforge.learner.checkpoint import latest_checkpoint, load_policy
from gaitforge.learner.evaluate import evaluate_policy
from gaitforge.learner.job import Job, load_job
from gaitforge.learner.trainer import Trainer
from gaitforge.service.ops.train import ProgressLog
from gaitforge.workers.scenes import load_scene
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

console = Console(width=None if sys.stdout.isatty() else 140)  # a log file gets the whole table
logger = logging.getLogger("bench.blending")
LOG_EVERY_S = 10.0
TRANSITIONS = ("blend", "distil", "scratch")
VARIANTS = ("blend-cloned", "continue")  # on request: --transitions


def narrow_elbow(out: Path) -> Path:
    """elbow-reach with targets drawn from [0.9, 1.2] rad only (stage 0 of the default)."""
    raw = load_scene("elbow-reach").model_dump(mode="json")
    raw.update(name="elbow-reach-narrow")
    raw["task"]["reach_range"] = [0.9, 1.2]
    path = out / "elbow-reach-narrow.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def stage_transition(transition: str, ramp: int, warmup: int) -> dict:
    """A stage's ``transition`` and ``blend`` for one of TRANSITIONS (``blend-cloned``: a
    blend whose pi_new is first cloned from pi_old, ``blend.clone_actor``)."""
    blend = {"ramp_env_steps": ramp, "critic_warmup_env_steps": warmup,
             "clone_actor": transition == "blend-cloned"}  # fmt: skip
    return {"transition": transition.removesuffix("-cloned"), "blend": blend}


def job_for(args: argparse.Namespace, seed: int, transition: str, from_scene: str) -> Job:
    ramp = max(1, args.to_steps // 2)
    return Job.model_validate({
        "name": f"blending-{transition}-{seed}",
        "seed": seed,
        "network": {"hidden": args.small},
        "ppo": {"batch_env_steps": args.batch, "minibatch_size": args.batch // 4,
                "lr": args.lr, "mirror": args.mirror},
        "workers": {"num_workers": args.workers, "envs_per_worker": 8, "fragment_length": 64},
        "checkpoint": {"every_iters": 1000, "keep_last": 1},
        "stages": [
            {"scene": from_scene, "env_steps": args.from_steps},
            {"scene": args.to_scene, "env_steps": args.to_steps, "network": {"hidden": args.big},
             **stage_transition(transition, ramp, args.batch)},
        ],
    })  # fmt: skip


def job_from_file(args: argparse.Namespace, seed: int, transition: str) -> Job:
    """``--job``'s file with its first stage made the transition under test: ``--big`` grown
    from its ``init_from`` checkpoint (``continue``: that network as it is) for
    ``--to-steps`` env steps, alpha ramped over half of them."""
    job, _ = load_job(args.job)
    first = job.stages[0].model_dump()
    first.update(env_steps=args.to_steps, transition=transition, promote=[], network=None)
    if transition != "continue":
        first["network"] = {"hidden": args.big, "init_std": job.network.init_std}
        first.update(stage_transition(transition, max(1, args.to_steps // 2),
                                      job.ppo.batch_env_steps))  # fmt: skip
    raw = job.model_dump()
    raw.update(name=f"blending-{transition}-{seed}", seed=seed, stages=[first])
    raw["checkpoint"] = {"every_iters": 1000, "keep_last": 1, "record_every_iters": 0}
    if args.workers:
        raw["workers"]["num_workers"] = args.workers
    return Job.model_validate(raw)


def run_seed(args: argparse.Namespace, seed: int, from_scene: str, progress: Progress) -> dict:
    """Stage 0 once, then each transition from a copy of its final checkpoint; with
    ``--job``, each transition from the job's ``init_from`` checkpoint."""

    def tick(task_id: int, label: str):
        """The progress bar on a terminal; off one, a line naming the run, then the trainer's
        status lines (``ProgressLog``, every LOG_EVERY_S)."""
        if console.is_terminal:
            return lambda m: progress.update(task_id, completed=m["stage_env_steps"])
        logger.info("seed %d: %s", seed, label)
        return ProgressLog(every_s=LOG_EVERY_S)

    base = args.out / f"seed{seed}" / "stage0"
    if args.job is None and latest_checkpoint(base / "checkpoints") is None:
        task = progress.add_task(f"seed {seed} stage 0", total=args.from_steps)
        stage0 = job_for(args, seed, "blend", from_scene).model_dump()
        stage0["stages"] = stage0["stages"][:1]
        Trainer(Job.model_validate(stage0), base, on_iteration=tick(task, "stage 0"),
                tensorboard=False).run()  # fmt: skip
    results = {}
    for transition in args.transitions:
        run_dir = args.out / f"seed{seed}" / transition
        shutil.rmtree(run_dir, ignore_errors=True)
        (run_dir / "checkpoints").mkdir(parents=True)
        if args.job is None:
            job = job_for(args, seed, transition, from_scene)
            stage0_end = _stage_end(base)
            shutil.copytree(stage0_end, run_dir / "checkpoints" / stage0_end.name)
        else:
            job = job_from_file(args, seed, transition)
        stage = len(job.stages) - 1
        task = progress.add_task(f"seed {seed} {transition}", total=args.to_steps)
        start = time.perf_counter()
        trainer = Trainer(job, run_dir, on_iteration=tick(task, transition), tensorboard=False)
        history = [h for h in trainer.run() if h["stage"] == stage]
        policy, _ = load_policy(latest_checkpoint(run_dir / "checkpoints"))
        evaluation = evaluate_policy(
            policy, trainer.scenes[stage], job.stage_backend(stage),
            episodes=args.eval_episodes, seed=10_000,
        )  # fmt: skip
        results[transition] = {
            "curve": [(h["stage_env_steps"], h["return"]) for h in history],
            "first_return": history[0]["return"],
            "final_train_return": history[-1]["return"],
            "eval_return": evaluation.return_.mean,
            "eval_fall_rate": evaluation.fall_rate.value,
            "eval_speed_m_s": evaluation.mean_speed_m_s.mean,
            "wall_s": time.perf_counter() - start,
        }
    return results


def _stage_end(base: Path) -> Path:
    path = latest_checkpoint(base / "checkpoints")
    assert path is not None, f"stage 0 left no checkpoint in {base}"
    return path


SUMMARY = {
    "first_return": "return after switch", "final_train_return": "final train return",
    "eval_return": "eval return", "eval_fall_rate": "eval falls", "eval_speed_m_s": "eval m/s",
    "wall_s": "wall s",
}  # fmt: skip


def summarise(per_seed: list[dict], transitions: list[str]) -> Table:
    table = Table(title="Stage transition at equal env steps (mean ± std over seeds)")
    for col in ("transition", *SUMMARY.values()):
        table.add_column(col, justify="right")
    for transition in transitions:
        cells = []
        for key in SUMMARY:
            values = [seed[transition][key] for seed in per_seed]
            spread = statistics.stdev(values) if len(values) > 1 else 0.0
            digits = 2 if key in ("eval_fall_rate", "eval_speed_m_s") else 1
            cells.append(f"{statistics.mean(values):.{digits}f} ± {spread:.{digits}f}")
        table.add_row(transition, *cells)
    return table


def plot(per_seed: list[dict], transitions: list[str], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    for index, transition in enumerate(transitions):
        colour = f"C{index}"
        for i, seed in enumerate(per_seed):
            steps, returns = zip(*seed[transition]["curve"], strict=True)
            ax.plot(steps, returns, color=colour, alpha=0.7,
                    label=transition if i == 0 else None)  # fmt: skip
    ax.set_xlabel("env steps in the new stage")
    ax.set_ylabel("training return (last 100 episodes)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--from-scene", default=None, help="default: elbow-reach, narrow")
    parser.add_argument("--to-scene", default="elbow-reach")
    parser.add_argument("--from-steps", type=int, default=60_000)
    parser.add_argument("--to-steps", type=int, default=60_000)
    parser.add_argument("--small", type=int, nargs="+", default=[32, 32])
    parser.add_argument("--big", type=int, nargs="+", default=[128, 128])
    parser.add_argument("--batch", type=int, default=2048)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--mirror", action="store_true")
    parser.add_argument(
        "--workers",
        type=int,
        default=0,
        help="Ray actors (0: in-process; with --job: the job's own)",
    )
    parser.add_argument(
        "--job",
        type=Path,
        default=None,
        help="a job file whose first stage starts from init_from: the "
        "transition measured (no stage 0)",
    )
    parser.add_argument(
        "--transitions", nargs="+", default=list(TRANSITIONS), choices=[*TRANSITIONS, *VARIANTS]
    )
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("bench/results/blending"))
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    if "continue" in args.transitions and args.job is None:
        parser.error("--transitions continue: only with --job (without it every transition "
                     "grows the network)")  # fmt: skip
    if args.eval_episodes < 1:
        parser.error("--eval-episodes must be >= 1")
    if args.job is not None:
        if not args.job.is_file():
            parser.error(f"--job: no file {args.job}")
        if load_job(args.job)[0].init_from is None:
            parser.error(f"--job: {args.job} has no init_from (the network to grow from)")
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(message)s")
    for name in (logger.name, "gaitforge.service.ops.train"):  # this file's and ProgressLog's
        logging.getLogger(name).setLevel(logging.INFO)
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    from_scene = args.from_scene or ("" if args.job else str(narrow_elbow(args.out)))
    if args.from_scene is not None:
        load_scene(args.from_scene)  # one-line error for an unknown scene
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, disable=not console.is_terminal) as progress:
        per_seed = [run_seed(args, seed, from_scene, progress) for seed in range(args.seeds)]
    console.print(summarise(per_seed, args.transitions))
    (args.out / "blending.json").write_text(json.dumps(per_seed, indent=1))
    plot(per_seed, args.transitions, args.out / "blending.png")
    console.print(f"written: {args.out / 'blending.json'}, {args.out / 'blending.png'} "
                  f"(machine: {os.cpu_count()} CPUs)")  # fmt: skip


if __name__ == "__main__":
    main()
