"""Learning curves and wall-clock to target, gaitforge's PPO beside RLlib's on the same env.

Usage: python bench/learning.py [--tasks elbow-reach stand-2d walk-2d] [--minutes M ...]
                                [--seeds S ...] [--eval-episodes N] [--no-rllib | --no-gaitforge]
                                [--workers W] [--out DIR]
       python bench/learning.py --merge A/learning.json B/learning.json --out DIR

A task is an example job (``examples/<task>.yaml``) or a job file's path (``*.yaml``, named
by its file name without the suffix: a variant of an example kept beside its results); its
target is its last stage's promotion rule(s) (a curriculum's earlier stages are the way
there; their wall clock counts): elbow-reach ``return >= -12 over 50``; stand-2d
``survival >= 0.95 over 100`` (the whole 5 s episode without a fall); walk-2d ``speed >= 1.0`` and
``fall_rate <= 0.1`` over 100 10-s episodes. Each framework gets the same wall-clock budget
per task (``--minutes``, default 3, 5 and 30) on the same scene (with the job's overrides,
e.g. 25 Hz control), the same number of rollout workers (``--workers``, default: CPUs less
one for the learner), network, batch size, epochs, learning rate and discount. gaitforge
stops at the target; RLlib (``bench/rllib_runner.py``) goes through the same stages, each
for its env-step budget, and is checked against the last stage's rules after each of its
iterations, with episode statistics logged by a callback as means over the rules' largest
window.

gaitforge runs once per seed (``--seeds``, the job's ``seed``; RLlib runs with the first
seed only); each run's newest checkpoint (RLlib's final module, its mean action) is then
evaluated deterministically over ``--eval-episodes`` episodes of the scene its run ended on
(``learner.evaluation.evaluate``: fall rate, mean speed and, on imitation scenes, what the
evaluation reports of the tracking), and the table gives each seed and the median over seeds.

Prints a table (target reached in training, i.e. promoted on the stochastic episodes'
window?, wall-clock and env steps to it, or the last values; target met on the
deterministic evaluation's means, the issue's judge?),
writes ``learning.json`` and ``learning.png`` (each rule's metric and the return against
wall-clock time, one line per seed; a judged stage's deterministic evaluations, which the
curve keeps as ``eval_*``, as dots) to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import ray
from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint
from gaitforge.learner.job import Job, PromotionRule, load_job
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.ray_start import start_ray
from gaitforge.workers.scenes import Scene
from rich.console import Console
from rich.table import Table
from rllib_runner import run_rllib  # bench/rllib_runner.py (this script's folder is on sys.path)

# off a terminal (a log file) wide enough for the table rather than rich's 80 columns
console = Console(width=None if Console().is_terminal else 160)
EXAMPLES = Path(__file__).parents[1] / "examples"
DEFAULT_MINUTES = {"elbow-reach": 3.0, "stand-2d": 5.0, "walk-2d": 30.0}


def run_gaitforge(
    job: Job,
    scenes: list[Scene],
    judged: dict[int, Scene],
    minutes: float,
    out: Path,
    eval_episodes: int,
) -> dict:
    curve: list[dict] = []
    start = time.monotonic()
    last = len(job.stages) - 1
    rules = job.stages[last].promote

    def record(m: dict) -> None:
        means = {r.metric: m[r.metric] for r in rules}
        # a judged stage's deterministic evaluations (learner.evaluation.stage_judge), where one ran
        evaluated = {k: v for k, v in m.items() if k.startswith(("eval_", "kept_"))}
        curve.append(
            {
                "wall_s": time.monotonic() - start,
                "env_steps": m["env_steps"],
                "stage": m["stage"],
                "return": m["return"],
                **means,
                **evaluated,
            }
        )
        console.log(f"gaitforge {job.name}: {curve[-1]}")

    trainer = Trainer(job, out, scenes, judged, on_iteration=record, tensorboard=False)
    history = trainer.run(max_seconds=minutes * 60)
    reached = next(
        (h for h in history if h["stage"] == last and (h["verdict"] or "").startswith("promoted")),
        None,
    )
    summary = _summary(curve, reached is not None)
    if eval_episodes:
        summary["evaluation"] = evaluate_run(out, eval_episodes)
        summary["met"] = met_deterministically(rules, summary["evaluation"])
    return summary


def evaluate_run(run_dir: Path, episodes: int) -> dict:
    """The run's newest checkpoint, deterministic, ``episodes`` episodes of its own scene:
    every mean, rate and interval the evaluation reports (per-episode rows left out)."""
    report = evaluate_checkpoint(run_dir, episodes=episodes, modes=("deterministic",))
    result = report.to_dict()["results"]["deterministic"]
    result.pop("episodes", None)
    console.log(f"evaluated {run_dir}: {_headline(result)}")
    return result


def _headline(evaluation: dict) -> dict[str, float | None]:
    """The figures targets are stated in: return, fall rate, mean speed (m/s), and whatever
    imitation figures the evaluation reports (``tracking_*``, ``kept_*``)."""
    out = {
        "return": evaluation["return"]["mean"],
        "fall_rate": evaluation["fall_rate"]["value"],
        "speed": evaluation["mean_speed_m_s"]["mean"],
    }
    for key, value in evaluation.items():
        if key.startswith(("tracking", "kept")) and isinstance(value, dict):
            out[key] = value.get("mean", value.get("value"))
    return out


def rule_means(evaluation: dict) -> dict[str, float | None]:
    """The evaluation's means of the figures promotion rules read (``learner.job.METRICS``),
    so a target can be judged on deterministic episodes rather than the stochastic training
    window; an evaluation written before ``survival_rate`` existed has no ``survival``."""
    means = {
        **_headline(evaluation),  # return, fall_rate, speed: the rules' names already
        "distance": evaluation["distance_m"]["mean"],
        "length": evaluation["time_s"]["mean"],
    }
    if "survival_rate" in evaluation:
        means["survival"] = evaluation["survival_rate"]["value"]
    return means


def met_deterministically(rules: list[PromotionRule], evaluation: dict) -> bool | None:
    """Whether every rule passes on the deterministic evaluation's means (over all its
    episodes, whatever the rule's window); None where a rule's figure is missing."""
    means = rule_means(evaluation)
    if any(means.get(r.metric) is None for r in rules):
        return None
    return all(r.passes(means[r.metric]) for r in rules)


def _summary(curve: list[dict], reached: bool) -> dict:
    last = curve[-1] if curve else {}
    return {
        "reached": reached,
        "wall_s": last.get("wall_s"),
        "env_steps": last.get("env_steps"),
        "last": last,
        "curve": curve,
    }


def _yes_no(value: bool | None) -> str:
    return "-" if value is None else ("yes" if value else "no")


def _cell(values: dict) -> str:
    """One ``name value`` line per figure (floats to 3 decimals), for a table cell."""
    return "\n".join(f"{k} {round(v, 3) if isinstance(v, float) else v}" for k, v in values.items())


def median_evaluation(runs: dict[str, dict]) -> dict[str, float]:
    """Per headline figure, the median over the runs that were evaluated."""
    heads = [_headline(r["evaluation"]) for r in runs.values() if "evaluation" in r]
    keys = {k for h in heads for k in h}
    return {
        k: statistics.median(v)
        for k in sorted(keys)
        if (v := [h[k] for h in heads if h.get(k) is not None])
    }


def table(results: dict) -> Table:
    out = Table(title=f"Learning to target, same wall-clock budget ({os.cpu_count()} CPUs)")
    for col in (
        "task",
        "run",
        "target",
        "reached (training)",
        "wall s",
        "env steps",
        "last values",
        "met (deterministic)",
        "deterministic evaluation",
    ):
        out.add_column(col, overflow="fold")
    for task, by_task in results.items():
        for name, r in by_task["runs"].items():
            # the training figures; the judges' (eval_*, kept_*) are the plot's dots
            last = {
                k: v
                for k, v in r["last"].items()
                if k not in ("wall_s", "env_steps") and not k.startswith(("eval_", "kept_"))
            }
            evaluation = _headline(r["evaluation"]) if "evaluation" in r else {}
            out.add_row(
                task,
                name,
                by_task["target"],
                _yes_no(r["reached"]),
                f"{r['wall_s'] or 0:.0f}",
                f"{r['env_steps'] or 0:,}",
                _cell(last),
                _yes_no(r.get("met")),
                _cell(evaluation),
            )
        gaitforge = {n: r for n, r in by_task["runs"].items() if n.startswith("gaitforge")}
        if len(gaitforge) > 1:
            reached = sum(r["reached"] for r in gaitforge.values())
            judged = [r["met"] for r in gaitforge.values() if r.get("met") is not None]
            out.add_row(
                task,
                f"gaitforge median of {len(gaitforge)}",
                by_task["target"],
                f"{reached}/{len(gaitforge)}",
                "",
                "",
                "",
                f"{sum(judged)}/{len(judged)}" if judged else "-",
                _cell(median_evaluation(gaitforge)),
            )
    return out


def plot(results: dict, path: Path) -> None:
    """Per task, panels against wall-clock minutes: each promotion rule's metric (with its
    threshold) and the return, one line per run over its training episodes; where a stage
    was judged on deterministic evaluations (``eval_<metric>``), those as dots of the run's
    colour."""
    rows = max(len(_rule_lines(by_task)) for by_task in results.values()) + 1
    fig, axes = plt.subplots(
        rows, len(results), figsize=(5 * len(results), 3.2 * rows), squeeze=False
    )
    for column, (task, by_task) in enumerate(results.items()):
        lines = _rule_lines(by_task)
        panels = [(axes[i][column], metric) for i, (metric, _) in enumerate(lines)]
        panels.append((axes[rows - 1][column], "return"))
        for name, r in by_task["runs"].items():
            xs = [p["wall_s"] / 60 for p in r["curve"]]
            for ax, key in panels:
                (line,) = ax.plot(xs, [p.get(key, float("nan")) for p in r["curve"]], label=name)
                judged = [
                    (x, p[f"eval_{key}"])
                    for x, p in zip(xs, r["curve"], strict=True)
                    if f"eval_{key}" in p
                ]
                if judged:
                    ax.plot(
                        *zip(*judged, strict=True),
                        "o",
                        color=line.get_color(),
                        markersize=3,
                        label=f"{name}, deterministic",
                    )
        for (ax, metric), (_, threshold) in zip(panels, lines, strict=False):
            ax.axhline(threshold, color="grey", linestyle="--", linewidth=1)
            ax.set_ylabel(metric)
        axes[0][column].set_title(task)
        axes[0][column].legend(fontsize="small")
        axes[rows - 1][column].set_ylabel("return (last 100 episodes)")
        axes[rows - 1][column].set_xlabel("wall-clock min")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _rule_lines(by_task: dict) -> list[tuple[str, float]]:
    """A task's promotion rules as (metric, threshold); results written before ``rules``
    was kept name only the first."""
    rules = by_task.get("rules") or [{"metric": by_task["metric"], "value": by_task["threshold"]}]
    return [(rule["metric"], rule["value"]) for rule in rules]


def merge(paths: list[Path]) -> dict:
    """``learning.json`` files of separate invocations (e.g. seeds run one after another)
    as one: per task, the runs of all of them."""
    merged: dict = {}
    for path in paths:
        for task, by_task in json.loads(path.read_text()).items():
            merged.setdefault(task, {**by_task, "runs": {}})["runs"].update(by_task["runs"])
    return merged


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(DEFAULT_MINUTES))
    parser.add_argument("--minutes", type=float, nargs="+", default=None)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=100,
        help="deterministic episodes per run at the end (0: none)",
    )
    parser.add_argument("--no-rllib", action="store_true")
    parser.add_argument("--no-gaitforge", action="store_true", help="RLlib only")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", type=Path, default=Path("bench/results/learning"))
    parser.add_argument(
        "--merge",
        type=Path,
        nargs="+",
        help="only merge these learning.json files into --out (table, plot)",
    )
    args = parser.parse_args()
    if args.merge:
        results = merge(args.merge)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "learning.json").write_text(json.dumps(results, indent=1))
        console.print(table(results))
        plot(results, args.out / "learning.png")
        return
    minutes = args.minutes or [DEFAULT_MINUTES.get(Path(t).stem, 5.0) for t in args.tasks]
    if len(minutes) != len(args.tasks):
        parser.error("--minutes: one value per task")
    logging.basicConfig(level=logging.WARNING)
    start_ray()
    workers = args.workers or max(1, int(ray.cluster_resources()["CPU"]) - 1)
    results: dict = {}
    for task_arg, budget in zip(args.tasks, minutes, strict=True):
        job_file = Path(task_arg) if task_arg.endswith((".yaml", ".yml")) else None
        task = job_file.stem if job_file else task_arg
        job, scenes, judged = load_job(job_file or EXAMPLES / f"{task}.yaml")
        rules = job.stages[-1].promote
        runs = {}
        for seed in [] if args.no_gaitforge else args.seeds:
            raw = job.model_dump()
            raw["workers"]["num_workers"] = workers
            raw["seed"] = seed
            seeded = Job.model_validate(raw)
            run_dir = args.out / "runs" / task / f"seed-{seed}"
            runs[f"gaitforge seed {seed}"] = run_gaitforge(
                seeded, scenes, judged, budget, run_dir, args.eval_episodes
            )
        if not args.no_rllib:
            raw = job.model_dump()
            raw["workers"]["num_workers"] = workers
            raw["seed"] = args.seeds[0]
            curve, reached, evaluation = run_rllib(
                Job.model_validate(raw), scenes, budget, workers, args.eval_episodes
            )
            rllib = runs[f"rllib seed {args.seeds[0]}"] = _summary(curve, reached)
            if evaluation is not None:
                rllib["evaluation"] = evaluation
                rllib["met"] = met_deterministically(rules, evaluation)
                console.log(f"evaluated RLlib's module: {_headline(evaluation)}")
        results[task] = {
            "target": " and ".join(str(r) for r in rules),
            "minutes": budget,
            "metric": rules[0].metric,
            "threshold": rules[0].value,
            "rules": [{"metric": r.metric, "value": r.value} for r in rules],
            "runs": runs,
        }
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "learning.json").write_text(json.dumps(results, indent=1))
    console.print(table(results))
    plot(results, args.out / "learning.png")
    console.print(f"written: {args.out / 'learning.json'}, {args.out / 'learning.png'}")


if __name__ == "__main__":
    main()
