"""One curriculum run, stage by stage: where each stage ended (env steps, wall clock of
training) and how it did, as a table, and the curve of the whole run as one PNG: training
return, mean speed and falls (the sampled policy's, over each update's episodes) against env
steps, the deterministic evaluations' speed and falls where stages evaluate, and the stage
boundaries marked. From the run's TensorBoard scalars (``train/*``; ``train_s`` is the
training wall clock, summed over resumes).

Usage: python bench/curriculum_run.py RUN_DIR --out run.png [--json-out stages.json]
"""

from __future__ import annotations

import argparse
import json
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
SERIES = ("stage", "train_s", "return", "speed", "fall_rate", "eval_speed", "eval_fall_rate")
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


def plot_run(
    scalars: dict[str, dict[int, float]], rows: list[dict], names: list[str], out: Path
) -> None:
    """The run's curve (see the module's docstring) as a PNG at ``out``, each stage's
    boundary marked with its index and name (``names``, by stage index)."""
    figure, axes = plt.subplots(len(PANELS), 1, figsize=(10, 8), sharex=True)
    for ax, (training, evaluation, title) in zip(axes, PANELS, strict=True):
        series = sorted(scalars.get(training, {}).items())
        if series:
            ax.plot(
                [s / 1e6 for s, _ in series],
                [v for _, v in series],
                lw=0.8,
                label="training (sampled actions)",
            )
        if evaluation and scalars.get(evaluation):
            points = sorted(scalars[evaluation].items())
            ax.plot(
                [s / 1e6 for s, _ in points],
                [v for _, v in points],
                "o",
                ms=3,
                label="evaluation (mean actions, 100 episodes)",
            )
        for row in rows[1:]:
            ax.axvline(row["first_env_steps"] / 1e6, color="grey", ls="--", lw=0.7)
        ax.set_ylabel(title, fontsize="small")
    for position, row in enumerate(rows):
        index = row["stage"]
        name = names[index] if index < len(names) else ""
        axes[0].annotate(
            f"{index} {name}".strip(),
            (row["first_env_steps"] / 1e6, 1.0 + 0.07 * (position % 2)),
            xycoords=("data", "axes fraction"),
            fontsize="x-small",
            va="bottom",
        )
    axes[1].legend(fontsize="small")
    axes[-1].set_xlabel("env steps (M)")
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--json-out", type=Path)
    args = parser.parse_args()
    scalars = run_scalars(args.run)
    rows = stage_rows(scalars)
    names = stage_names(args.run)
    plot_run(scalars, rows, names, args.out)
    table = Table(
        "stage",
        "name",
        "env steps",
        "of which in it",
        "train min",
        "of which in it",
        "eval speed m/s",
        "eval falls",
    )
    for row in rows:
        minutes = "-" if row["train_s"] is None else f"{row['train_s'] / 60:.1f}"
        stage_min = "-" if "stage_s" not in row else f"{row['stage_s'] / 60:.1f}"
        speed = "-" if "eval_speed" not in row else f"{row['eval_speed']:.2f}"
        falls = "-" if "eval_fall_rate" not in row else f"{100 * row['eval_fall_rate']:.0f} %"
        index = row["stage"]
        table.add_row(
            str(index),
            names[index] if index < len(names) else "",
            f"{row['env_steps']:,}",
            f"{row['stage_env_steps']:,}",
            minutes,
            stage_min,
            speed,
            falls,
        )
    console.print(table)
    if args.json_out is not None:
        args.json_out.write_text(json.dumps(rows, indent=2) + "\n")
    console.print(f"written: {args.out}")


if __name__ == "__main__":
    main()
