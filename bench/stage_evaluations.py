"""The in-training evaluations of runs (stages with ``evaluate``,
``learner.evaluation.stage_judge``): falls and mean speed of the mean policy against env
steps, from each run's TensorBoard scalars, as a table and a PNG (one line per run).
``--training`` plots the training episodes' falls and speed instead (the sampled policy's,
over each update's episodes), for runs without evaluations.

Usage: python bench/stage_evaluations.py RUN_DIR [RUN_DIR ...] --out evaluations.png
                                         [--labels A B ...] [--training]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from rich.console import Console
from rich.table import Table
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

console = Console()
EVALUATION = {"eval_fall_rate": "falls (fraction)", "eval_speed": "mean speed (m/s)"}
TRAINING = {"fall_rate": "training falls (fraction)", "speed": "training speed (m/s)"}


def scalar_series(run_dir: Path, series: dict[str, str]) -> dict[str, list]:
    """Each of ``series`` (names of ``train/`` scalars) in ``run_dir/tb``: (env steps,
    value) pairs, in step order.

    Raises:
        SystemExit: no TensorBoard scalars there, or not those among them.
    """
    events = EventAccumulator(str(run_dir / "tb"), size_guidance={"scalars": 0})
    events.Reload()
    tags = events.Tags().get("scalars", [])
    if f"train/{next(iter(series))}" not in tags:
        raise SystemExit(f"{run_dir}: no {next(iter(series))} scalars in {run_dir / 'tb'}")
    return {
        name: sorted((e.step, e.value) for e in events.Scalars(f"train/{name}")) for name in series
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--labels", nargs="+", default=None)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--training", action="store_true", help="the training episodes' falls and speed"
    )
    args = parser.parse_args()
    wanted = TRAINING if args.training else EVALUATION
    labels = args.labels or [str(run) for run in args.runs]
    if len(labels) != len(args.runs):
        parser.error("--labels: one per run")
    figure, axes = plt.subplots(1, len(wanted), figsize=(6 * len(wanted), 4))
    table = Table("run", "env steps", *wanted.values())
    for run, label in zip(args.runs, labels, strict=True):
        series = scalar_series(run, wanted)
        for ax, (name, title) in zip(axes, wanted.items(), strict=True):
            steps, values = zip(*series[name], strict=True)
            ax.plot([s / 1e6 for s in steps], values, marker="o", label=label)
            ax.set_xlabel("env steps (M)")
            ax.set_title(title)
        for (step, falls), (_, speed) in zip(*series.values(), strict=True):
            table.add_row(label, f"{step:,}", f"{100 * falls:.0f} %", f"{speed:.2f}")
    axes[0].legend()
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out, dpi=100)
    console.print(table)
    console.print(f"written: {args.out}")


if __name__ == "__main__":
    main()
