"""Curriculum runs judged stage by stage on the episodes nobody picked: for each stage with
promotion rules, the network it ended with (``RUN/best/stage-<i>``) on the scene it trained
on as the catalogue composes it (the stage's ``scene_set`` left out: the scene the README
names for it), ``--episodes`` deterministic episodes from ``--seed``; a stage whose scene
draws its target speed on ``--sweep-episodes`` episodes instead, also swept at 0 / 10 / 20 /
30 % slower. One table: falls and mean speed per run and stage, and the median over the
runs. ``--reports DIR`` also keeps each stage's whole evaluation report
(``DIR/<label>/<stage>.json``, as ``gaitforge evaluate --json-out`` writes it), the one
``gaitforge ship --evaluation`` cites.

Usage: python bench/curriculum_judge.py RUN [RUN ...] [--labels seed-0 ...] [--episodes 100]
           [--sweep-episodes 300] [--seed 0] [--json-out judged.json] [--reports DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

# bench/curriculum_run.py (this script's folder is on sys.path)
from curriculum_run import job_stages
from gaitforge.learner.checkpoint import latest_checkpoint
from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint
from gaitforge.learner.evaluation.results import EvaluationReport, ModeResult, write_json
from gaitforge.workers.scenes import load_scene
from rich.console import Console
from rich.table import Table

console = Console()
SWEEP = (0.0, 0.1, 0.2, 0.3)
"""target-speed reductions of the sweep (as ``gaitforge evaluate --sweep``)"""


def judged_stages(run_dir: Path) -> list[tuple[int, str, str]]:
    """(index, name, scene) of each stage with promotion rules, from the job in the run's
    newest checkpoint.

    Raises:
        SystemExit: the run has no checkpoint.
    """
    stages = job_stages(run_dir)
    if not stages:
        raise SystemExit(f"{run_dir}: no checkpoints")
    return [
        (index, stage.get("name") or f"stage-{index}", stage["scene"])
        for index, stage in enumerate(stages)
        if stage.get("promote")
    ]


def figures(result: ModeResult) -> dict[str, Any]:
    """Falls (count of episodes) and mean speed (m/s, over every episode) of one result."""
    return {
        "falls": result.fall_rate.count,
        "episodes": len(result.episodes),
        "speed_m_s": result.mean_speed_m_s.mean,
    }


def evaluate_stage(
    checkpoint: Path, scene: str, episodes: int, sweep_episodes: int, seed: int
) -> EvaluationReport:
    """``checkpoint`` on catalogue ``scene`` over ``episodes`` deterministic episodes or, if
    the scene draws its target speed, over ``sweep_episodes`` with the sweep."""
    sweeps = load_scene(scene).task.target_speed_range is not None
    return evaluate_checkpoint(
        checkpoint,
        scene=scene,
        episodes=sweep_episodes if sweeps else episodes,
        seed=seed,
        sweep=SWEEP if sweeps else None,
    )


def judge_stage(checkpoint: Path, scene: str, report: EvaluationReport) -> dict[str, Any]:
    """The figures of ``checkpoint``'s ``report`` on ``scene``, and the sweep's (each
    point's target in m/s) if it was swept."""
    judged = {"checkpoint": str(checkpoint), "scene": scene}
    judged.update(figures(report.results["deterministic"]))
    if report.sweep:
        judged["sweep"] = [
            {"target_m_s": point.target_speed_m_s, **figures(point.result)}
            for point in report.sweep
        ]
    return judged


def percent(value: float) -> str:
    """A share in percent to one decimal, without a trailing ``.0`` (2 of 300: "0.7")."""
    return f"{value:.1f}".removesuffix(".0")


def cell(judged: dict[str, Any] | None) -> str:
    """One run's stage as a table cell: falls in percent at its speed, and the sweep's falls."""
    if judged is None:
        return "-"
    text = (
        f"{percent(100 * judged['falls'] / judged['episodes'])} % at {judged['speed_m_s']:.2f} m/s"
    )
    if judged.get("sweep"):
        falls = " / ".join(str(point["falls"]) for point in judged["sweep"])
        text += f"; sweep {falls} of {judged['sweep'][0]['episodes']}"
    return text


def median_cell(runs: list[dict[str, Any]]) -> str:
    """The median over runs of one stage's falls (percent), speed and sweep falls."""
    if not runs:
        return "-"
    falls = statistics.median(100 * r["falls"] / r["episodes"] for r in runs)
    speed = statistics.median(r["speed_m_s"] for r in runs)
    text = f"{percent(falls)} % at {speed:.2f} m/s"
    sweeps = [r["sweep"] for r in runs if r.get("sweep")]
    if sweeps:
        points = zip(*sweeps, strict=True)
        text += "; sweep " + " / ".join(
            f"{statistics.median(p['falls'] for p in point):g}" for point in points
        )
    return text


def table(judged: dict[str, dict[str, dict[str, Any]]]) -> Table:
    """Rows: stages (in their order in the first run); columns: each run and the median."""
    labels = list(judged)
    stages = list(dict.fromkeys(stage for run in judged.values() for stage in run))
    out = Table("stage", *labels, f"median of {len(labels)}")
    for stage in stages:
        runs = [judged[label].get(stage) for label in labels]
        out.add_row(
            stage, *(cell(r) for r in runs), median_cell([r for r in runs if r is not None])
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--labels", nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--sweep-episodes", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json-out", type=Path)
    parser.add_argument("--reports", type=Path, help="keep each stage's evaluation report here")
    args = parser.parse_args()
    labels = args.labels or [run.name for run in args.runs]
    if len(labels) != len(args.runs):
        raise SystemExit(f"--labels: {len(labels)} given for {len(args.runs)} runs")
    judged: dict[str, dict[str, dict[str, Any]]] = {}
    for label, run in zip(labels, args.runs, strict=True):
        judged[label] = {}
        for index, name, scene in judged_stages(run):
            checkpoint = latest_checkpoint(run / "best" / f"stage-{index}")
            if checkpoint is None:
                console.print(f"{label}: stage {index} {name}: no best network kept")
                continue
            console.print(f"{label}: stage {index} {name} on {scene} ...")
            report = evaluate_stage(
                checkpoint, scene, args.episodes, args.sweep_episodes, args.seed
            )
            judged[label][name] = judge_stage(checkpoint, scene, report)
            if args.reports is not None:
                write_json(report, args.reports / label / f"{name}.json")
    console.print(table(judged))
    if args.json_out is not None:
        args.json_out.write_text(json.dumps(judged, indent=2) + "\n")
        console.print(f"written: {args.json_out}")


if __name__ == "__main__":
    main()
