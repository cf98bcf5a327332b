"""Falls per point of speed-against-safety sweeps, counted per run and pooled over runs: the
A/B table of the obstacle stage's sweep (falls in N episodes at each target speed, the median
over seeds and the sum), the falls' episodes at chosen points, and a plot.

Usage: python bench/sweep_falls.py SWEEP.json [SWEEP.json ...] [--labels seed-0 ...]
           [--episodes-at 2.4 2.1] [--out falls.png]

Each file is one run's ``gaitforge evaluate RUN --sweep --json-out SWEEP.json`` (every file
swept at the same points on the same episodes). ``--episodes-at`` lists, for each run, the
episodes that fell at those target speeds (m/s): seed, time of the fall (s), distance (m) and
when the body first touched a sphere (s).
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table


def sweep_points(report: dict[str, Any]) -> dict[float, dict[str, Any]]:
    """{target speed (m/s, rounded to 0.01): the evaluation there} of a sweep report; each
    evaluation's ``fall_rate`` holds its falls (``count``) of ``n`` episodes."""
    if not report.get("sweep"):
        raise SystemExit(f"{report.get('checkpoint')}: not a sweep (gaitforge evaluate --sweep)")
    return {round(point["target_speed_m_s"], 2): point["result"] for point in report["sweep"]}


def episodes_per_point(points: dict[float, dict[str, Any]]) -> int:
    """Episodes at each sweep point (the same at every point)."""
    return next(iter(points.values()))["fall_rate"]["n"]


def falls_table(runs: list[dict[float, dict[str, Any]]], labels: list[str]) -> Table:
    """Falls (count of the episodes per point) and mean speed per run, the median over runs
    and the sum over runs (with its percentage)."""
    targets = list(runs[0])
    episodes = episodes_per_point(runs[0])
    table = Table(title=f"Falls in {episodes} episodes at each target speed")
    table.add_column("run")
    for target in targets:
        table.add_column(f"{target:.2f} m/s", justify="right")
    for label, points in zip(labels, runs, strict=True):
        table.add_row(
            label,
            *(
                f"{points[t]['fall_rate']['count']} ({points[t]['mean_speed_m_s']['mean']:.2f} m/s)"
                for t in targets
            ),
        )
    counts = {t: [points[t]["fall_rate"]["count"] for points in runs] for t in targets}
    table.add_row(
        f"median of {len(runs)}",
        *(f"{statistics.median(counts[t]):g}" for t in targets),
        style="bold",
    )
    pooled = len(runs) * episodes
    table.add_row(
        f"all (of {pooled})",
        *(f"{sum(counts[t])} ({100 * sum(counts[t]) / pooled:.1f} %)" for t in targets),
    )
    return table


def fallen_episodes_table(
    runs: list[dict[float, dict[str, Any]]], labels: list[str], targets: list[float]
) -> Table:
    """Each fall at ``targets``: run, target, episode seed, time (s), distance (m), first
    touch of a sphere (s; "-" when none before the fall)."""
    table = Table(title="Episodes that fell")
    for column in ("run", "target m/s", "episode seed", "fell at s", "distance m", "first touch s"):
        table.add_column(column, justify="right")
    for label, points in zip(labels, runs, strict=True):
        for target in targets:
            point = points.get(round(target, 2), {"episodes": []})
            for e in (e for e in point["episodes"] if e["fell"]):
                touch = e.get("first_obstacle_touch_s")
                table.add_row(
                    label,
                    f"{target:.2f}",
                    str(e["seed"]),
                    f"{e['time_s']:.2f}",
                    f"{e['distance_m']:.1f}",
                    "-" if touch is None else f"{touch:.2f}",
                )
    return table


def plot(runs: list[dict[float, dict[str, Any]]], labels: list[str], out: Path) -> None:
    """Falls (% of the episodes) against target speed: each run thin, all runs pooled bold."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    targets = sorted(runs[0])
    episodes = episodes_per_point(runs[0])
    counts = [[points[t]["fall_rate"]["count"] for t in targets] for points in runs]
    fig, ax = plt.subplots(figsize=(6, 4))
    for label, run_counts in zip(labels, counts, strict=True):
        ax.plot(
            targets, [100 * c / episodes for c in run_counts], "o-", lw=1, alpha=0.6, label=label
        )
    total = episodes * len(runs)
    ax.plot(
        targets,
        [100 * sum(c) / total for c in zip(*counts, strict=True)],
        "k-s",
        lw=2.5,
        label=f"all {len(runs)} ({total} episodes per point)",
    )
    ax.set_xlabel("target speed (m/s)")
    ax.set_ylabel("falls (% of episodes)")
    ax.set_title("Speed against safety")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweeps", nargs="+", type=Path, help="gaitforge evaluate --sweep JSONs")
    parser.add_argument("--labels", nargs="+", help="one per file (default: the file names)")
    parser.add_argument(
        "--episodes-at",
        nargs="*",
        type=float,
        default=[],
        help="target speeds (m/s) whose falls to list",
    )
    parser.add_argument("--out", type=Path, help="a PNG of falls against target speed")
    args = parser.parse_args()
    labels = args.labels or [path.stem for path in args.sweeps]
    if len(labels) != len(args.sweeps):
        raise SystemExit(f"--labels: {len(labels)} given for {len(args.sweeps)} files")
    runs = [sweep_points(json.loads(path.read_text())) for path in args.sweeps]
    if len({(tuple(points), episodes_per_point(points)) for points in runs}) != 1:
        raise SystemExit(
            "the sweeps differ in points or episodes per point; compare like with like"
        )
    console = Console(width=120)
    console.print(falls_table(runs, labels))
    if args.episodes_at:
        console.print(fallen_episodes_table(runs, labels, args.episodes_at))
    if args.out:
        plot(runs, labels, args.out)
        console.print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
