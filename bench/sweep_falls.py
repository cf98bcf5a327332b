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


def falls_per_point(report: dict[str, Any]) -> dict[float, list[dict[str, Any]]]:
    """{target speed (m/s, rounded to 0.01): the episodes that fell there} of a sweep report."""
    if not report.get("sweep"):
        raise SystemExit(f"{report.get('checkpoint')}: not a sweep (gaitforge evaluate --sweep)")
    return {
        round(point["target_speed_m_s"], 2): [e for e in point["result"]["episodes"] if e["fell"]]
        for point in report["sweep"]
    }


def episodes_per_point(report: dict[str, Any]) -> int:
    """Episodes at each sweep point (the same at every point)."""
    return len(report["sweep"][0]["result"]["episodes"])


def speeds_per_point(report: dict[str, Any]) -> dict[float, float]:
    """{target speed: the run's mean speed there (m/s)}."""
    return {
        round(point["target_speed_m_s"], 2): point["result"]["mean_speed_m_s"]["mean"]
        for point in report["sweep"]
    }


def falls_table(reports: list[dict[str, Any]], labels: list[str]) -> Table:
    """Falls (count of the episodes per point) and mean speed per run, the median over runs
    and the sum over runs (with its percentage)."""
    counts = [{t: len(f) for t, f in falls_per_point(r).items()} for r in reports]
    speeds = [speeds_per_point(r) for r in reports]
    targets = list(counts[0])
    episodes = episodes_per_point(reports[0])
    table = Table(title=f"Falls in {episodes} episodes at each target speed")
    table.add_column("run")
    for target in targets:
        table.add_column(f"{target:.2f} m/s", justify="right")
    for label, count, speed in zip(labels, counts, speeds, strict=True):
        table.add_row(label, *(f"{count[t]} ({speed[t]:.2f} m/s)" for t in targets))
    table.add_row(
        f"median of {len(reports)}",
        *(f"{statistics.median(c[t] for c in counts):g}" for t in targets),
        style="bold",
    )
    pooled = len(reports) * episodes
    sums = {t: sum(c[t] for c in counts) for t in targets}
    table.add_row(
        f"all (of {pooled})", *(f"{sums[t]} ({100 * sums[t] / pooled:.1f} %)" for t in targets)
    )
    return table


def fallen_episodes_table(
    reports: list[dict[str, Any]], labels: list[str], targets: list[float]
) -> Table:
    """Each fall at ``targets``: run, target, episode seed, time (s), distance (m), first
    touch of a sphere (s; "-" when none before the fall)."""
    table = Table(title="Episodes that fell")
    for column in ("run", "target m/s", "episode seed", "fell at s", "distance m", "first touch s"):
        table.add_column(column, justify="right")
    for label, report in zip(labels, reports, strict=True):
        per_point = falls_per_point(report)
        for target in targets:
            for e in per_point.get(round(target, 2), []):
                touch = e.get("first_obstacle_touch_s")
                table.add_row(
                    label, f"{target:.2f}", str(e["seed"]), f"{e['time_s']:.2f}",
                    f"{e['distance_m']:.1f}", "-" if touch is None else f"{touch:.2f}",
                )  # fmt: skip
    return table


def plot(reports: list[dict[str, Any]], labels: list[str], out: Path) -> None:
    """Falls (% of the episodes) against target speed: each run thin, all runs pooled bold."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    episodes = episodes_per_point(reports[0])
    fig, ax = plt.subplots(figsize=(6, 4))
    pooled: dict[float, int] = {}
    for label, report in zip(labels, reports, strict=True):
        per_point = falls_per_point(report)
        targets = sorted(per_point)
        ax.plot(targets, [100 * len(per_point[t]) / episodes for t in targets], "o-", lw=1,
                alpha=0.6, label=label)  # fmt: skip
        for t in targets:
            pooled[t] = pooled.get(t, 0) + len(per_point[t])
    targets = sorted(pooled)
    total = episodes * len(reports)
    ax.plot(targets, [100 * pooled[t] / total for t in targets], "k-s", lw=2.5,
            label=f"all {len(reports)} ({total} episodes per point)")  # fmt: skip
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
    parser.add_argument("--episodes-at", nargs="*", type=float, default=[],
                        help="target speeds (m/s) whose falls to list")  # fmt: skip
    parser.add_argument("--out", type=Path, help="a PNG of falls against target speed")
    args = parser.parse_args()
    labels = args.labels or [path.stem for path in args.sweeps]
    if len(labels) != len(args.sweeps):
        raise SystemExit(f"--labels: {len(labels)} given for {len(args.sweeps)} files")
    reports = [json.loads(path.read_text()) for path in args.sweeps]
    if len({episodes_per_point(r) for r in reports}) != 1:
        raise SystemExit("the sweeps differ in episodes per point; compare like with like")
    console = Console(width=120)
    console.print(falls_table(reports, labels))
    if args.episodes_at:
        console.print(fallen_episodes_table(reports, labels, args.episodes_at))
    if args.out:
        plot(reports, labels, args.out)
        console.print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
