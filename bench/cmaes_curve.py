"""The curve of CMA-ES searches: best and mean cost, and the best candidate's time alive and
speed, against wall-clock minutes, from each search's ``progress.csv``.

Usage: python bench/cmaes_curve.py RUN/cmaes/stage-0/progress.csv [MORE.csv ...]
    --labels from-rest mid-stride --out curve.png

``FIRST.csv+THEN.csv`` draws a search continued from another's tuned scene as one curve:
the continuation's generations follow the first search's, its minutes after the first's
last.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def read(path: Path) -> dict[str, list[float]]:
    """Each column of ``path`` as floats."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return {key: [float(row[key]) for row in rows] for key in rows[0]}


def read_joined(spec: str) -> dict[str, list[float]]:
    """The columns of ``FIRST.csv[+THEN.csv...]``, each continuation's ``wall_s`` (s)
    shifted to start where the search before it ended."""
    joined: dict[str, list[float]] = {}
    for part in spec.split("+"):
        columns = read(Path(part))
        offset = joined["wall_s"][-1] if joined else 0.0
        columns["wall_s"] = [s + offset for s in columns["wall_s"]]
        for key, values in columns.items():
            joined.setdefault(key, []).extend(values)
    return joined


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("progress", nargs="+", help="progress.csv, or FIRST.csv+THEN.csv")
    parser.add_argument("--labels", nargs="+")
    parser.add_argument("--out", type=Path, default=Path("cmaes-curve.png"))
    args = parser.parse_args()
    labels = args.labels or [Path(p.split("+")[0]).parent.name for p in args.progress]
    figure, (cost, alive, speed) = plt.subplots(1, 3, figsize=(13, 3.6))
    for path, label in zip(args.progress, labels, strict=True):
        columns = read_joined(path)
        minutes = [s / 60 for s in columns["wall_s"]]
        (line,) = cost.plot(minutes, columns["best"], label=f"{label}: best")
        cost.plot(minutes, columns["mean"], color=line.get_color(), alpha=0.4, label="mean")
        alive.plot(minutes, columns["best_alive"], color=line.get_color(), label=label)
        speed.plot(minutes, columns["best_speed"], color=line.get_color(), label=label)
    cost.set(xlabel="wall clock (min)", ylabel="cost (lower is better)")
    alive.set(xlabel="wall clock (min)", ylabel="best candidate: share of time alive")
    speed.set(xlabel="wall clock (min)", ylabel="best candidate: speed (m/s)")
    for axes in (cost, alive, speed):
        axes.grid(alpha=0.3)
        axes.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
