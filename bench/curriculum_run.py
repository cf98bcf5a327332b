"""Curriculum runs, stage by stage: where each stage ended (env steps, wall clock of
training) and how it did, as a table per run and, for several runs (seeds of one job), the
median per stage; and the curves of the whole runs as one PNG: training return, mean speed
and falls (the sampled policy's, over each update's episodes) against env steps, the
deterministic evaluations' speed and falls where stages evaluate, and the stage boundaries
marked. From each run's TensorBoard scalars (``train/*``; ``train_s`` is the training wall
clock, summed over resumes).

Usage: python bench/curriculum_run.py RUN [RUN ...] [--labels seed-0 ...] --out runs.png
           [--json-out stages.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from gaitforge.learner.checkpoint import latest_checkpoint
from gaitforge.learner.checkpoint_meta import read_meta
from rich.console import Console
from rich.table import Table
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

console = Console()
SERIES = (
    "stage",
    "train_s",
    "return",
    "length",
    "speed",
    "fall_rate",
    "eval_speed",
    "eval_fall_rate",
)
PANELS = (
    ("return", None, "training return (last 100 episodes)"),
    ("speed", "eval_speed", "mean speed (m/s)"),
    ("fall_rate", "eval_fall_rate", "falls (fraction)"),
)
"""(training scalar, evaluation scalar, title) of each panel"""


def run_scalars(run_dir: Path) -> dict[str, dict[int, float]]:
    """Each of ``SERIES`` in ``run_dir/tb``: env steps -> value (the last written at a step
    wins: a resumed run writes its steps again).

    Raises:
        SystemExit: no TensorBoard scalars there.
    """
    events = EventAccumulator(str(run_dir / "tb"), size_guidance={"scalars": 0})
    events.Reload()
    tags = set(events.Tags().get("scalars", []))
    if "train/stage" not in tags:
        raise SystemExit(f"{run_dir}: no training scalars in {run_dir / 'tb'}")
    return {
        name: {e.step: e.value for e in events.Scalars(f"train/{name}")}
        for name in SERIES
        if f"train/{name}" in tags
    }


def stage_rows(scalars: dict[str, dict[int, float]]) -> list[dict]:
    """Per stage: its index, the env steps and training seconds at its last iteration, the
    env steps and seconds it took, and its last evaluation (if it evaluates)."""
    steps = sorted(scalars["stage"])
    rows: list[dict] = []
    for step in steps:
        index = int(scalars["stage"][step])
        if not rows or rows[-1]["stage"] != index:
            rows.append({"stage": index, "first_env_steps": step})
        row = rows[-1]
        row["env_steps"] = step
        row["train_s"] = scalars.get("train_s", {}).get(step)
        for name in ("eval_speed", "eval_fall_rate"):
            if step in scalars.get(name, {}):
                row[name] = scalars[name][step]
    previous_steps, previous_s = 0, 0.0
    for row in rows:
        row["stage_env_steps"] = row["env_steps"] - previous_steps
        if row["train_s"] is not None:
            row["stage_s"] = row["train_s"] - previous_s
            previous_s = row["train_s"]
        previous_steps = row["env_steps"]
    return rows


def job_stages(run_dir: Path) -> list[dict]:
    """The stages of the job (as its file gives them) stored in the run's newest complete
    checkpoint; empty if there is none."""
    newest = latest_checkpoint(run_dir / "checkpoints")
    if newest is None:
        return []
    return (read_meta(newest).job or {}).get("stages", [])


def stage_names(run_dir: Path) -> list[str]:
    """The job's stage names (see :func:`job_stages`)."""
    return [stage.get("name", "") for stage in job_stages(run_dir)]


@dataclass
class Run:
    """One run as the plot and the tables read it."""

    label: str
    scalars: dict[str, dict[int, float]]
    rows: list[dict]
    names: list[str]
    """the job's stage names, by stage index"""

    def stage_name(self, index: int) -> str:
        """Stage ``index``'s name in the job; empty if the job does not name it."""
        return self.names[index] if index < len(self.names) else ""


def read_run(run_dir: Path, label: str) -> Run:
    """The run at ``run_dir``: its scalars, stage rows and stage names."""
    scalars = run_scalars(run_dir)
    return Run(label, scalars, stage_rows(scalars), stage_names(run_dir))


def plot_runs(runs: list[Run], out: Path) -> None:
    """The runs' curves (see the module's docstring) on one PNG at ``out``. One run: training
    and evaluation in two colours, each stage's boundary marked with its index and name.
    Several: one colour per run (training as a line, evaluations as dots), each run's stage
    boundaries dashed in its colour, the first run's named."""
    figure, axes = plt.subplots(len(PANELS), 1, figsize=(10, 8), sharex=True)
    several = len(runs) > 1
    for number, run in enumerate(runs):
        training_colour = f"C{number}" if several else "C0"
        evaluation_colour = f"C{number}" if several else "C1"
        for ax, (training, evaluation, title) in zip(axes, PANELS, strict=True):
            series = sorted(run.scalars.get(training, {}).items())
            if series:
                ax.plot(
                    [s / 1e6 for s, _ in series],
                    [v for _, v in series],
                    lw=0.8,
                    color=training_colour,
                    alpha=0.8 if several else 1.0,
                    label=f"{run.label} training" if several else "training (sampled actions)",
                )
            if evaluation and run.scalars.get(evaluation):
                points = sorted(run.scalars[evaluation].items())
                ax.plot(
                    [s / 1e6 for s, _ in points],
                    [v for _, v in points],
                    "o",
                    ms=3,
                    color=evaluation_colour,
                    label=f"{run.label} evaluation"
                    if several
                    else "evaluation (mean actions, 100 episodes)",
                )
            for row in run.rows[1:]:
                boundary_colour = training_colour if several else "grey"
                ax.axvline(row["first_env_steps"] / 1e6, color=boundary_colour, ls="--", lw=0.7)
            ax.set_ylabel(title, fontsize="small")
            if training == "fall_rate":
                ax.set_ylim(-0.03, 1.03)
    first = runs[0]
    for position, row in enumerate(first.rows):
        index = row["stage"]
        axes[0].annotate(
            f"{index} {first.stage_name(index)}".strip(),
            (row["first_env_steps"] / 1e6, 1.0 + 0.07 * (position % 2)),
            xycoords=("data", "axes fraction"),
            fontsize="x-small",
            va="bottom",
        )
    axes[1].legend(fontsize="small", ncol=len(runs))
    axes[-1].set_xlabel("env steps (M)")
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=100)


def minutes(seconds: float | None) -> str:
    """Seconds as minutes to one decimal; ``-`` where unknown."""
    return "-" if seconds is None else f"{seconds / 60:.1f}"


def run_table(run: Run) -> Table:
    """One run stage by stage: env steps and training minutes at its end and in it, and its
    last evaluation."""
    table = Table(
        "stage",
        "name",
        "env steps",
        "of which in it",
        "train min",
        "of which in it",
        "eval speed m/s",
        "eval falls",
        title=run.label,
    )
    for row in run.rows:
        speed = "-" if "eval_speed" not in row else f"{row['eval_speed']:.2f}"
        falls = "-" if "eval_fall_rate" not in row else f"{100 * row['eval_fall_rate']:.0f} %"
        index = row["stage"]
        table.add_row(
            str(index),
            run.stage_name(index),
            f"{row['env_steps']:,}",
            f"{row['stage_env_steps']:,}",
            minutes(row["train_s"]),
            minutes(row.get("stage_s")),
            speed,
            falls,
        )
    return table


def median_rows(runs: list[Run]) -> list[dict]:
    """Per stage that every run reached: the median over the runs of the env steps and
    training seconds it took (``stage_env_steps``, ``stage_s``) and of those at its end
    (``env_steps``, ``train_s``); a figure a run lacks is left out of its median."""
    reached = min(len(run.rows) for run in runs)
    medians = []
    for position in range(reached):
        rows = [run.rows[position] for run in runs]
        median = {"stage": rows[0]["stage"]}
        for key in ("stage_env_steps", "env_steps", "stage_s", "train_s"):
            values = [row[key] for row in rows if row.get(key) is not None]
            median[key] = statistics.median(values) if values else None
        medians.append(median)
    return medians


def median_table(runs: list[Run]) -> Table:
    """:func:`median_rows` as a table, stages named as the first run's job names them."""
    table = Table(
        "stage",
        "name",
        "env steps in it",
        "train min in it",
        "train min at its end",
        title=f"median of {len(runs)}",
    )
    for row in median_rows(runs):
        index = row["stage"]
        table.add_row(
            str(index),
            runs[0].stage_name(index),
            f"{row['stage_env_steps']:,.0f}",
            minutes(row["stage_s"]),
            minutes(row["train_s"]),
        )
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN")
    parser.add_argument("--labels", nargs="+", help="one per run (default: the folder names)")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--json-out", type=Path)
    args = parser.parse_args()
    labels = args.labels or [run.name for run in args.runs]
    if len(labels) != len(args.runs):
        parser.error(f"--labels: {len(labels)} given for {len(args.runs)} runs")
    runs = [read_run(run_dir, label) for run_dir, label in zip(args.runs, labels, strict=True)]
    plot_runs(runs, args.out)
    for run in runs:
        console.print(run_table(run))
    summary: dict = {run.label: run.rows for run in runs}
    if len(runs) > 1:
        console.print(median_table(runs))
        summary["median"] = median_rows(runs)
    if args.json_out is not None:
        args.json_out.write_text(json.dumps(summary, indent=2) + "\n")
    console.print(f"written: {args.out}")


if __name__ == "__main__":
    main()
