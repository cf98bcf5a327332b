"""Episode length against training time: the anchors' runs beside gaitforge's, as one PNG.

    python bench/myoleg_anchors/plot_progress.py --anchor sb3=RUNS/sb3-s0 [--anchor deprl=...]
        [--gaitforge learn-to-walk-3d=RUN ...] --out progress.png [--title T --minutes-label L]

An anchor run's ``progress.csv`` (``common.ProgressLog``: episodes ended in each 30 s of
training, their mean length in 0.01 s steps) and a gaitforge run's TensorBoard scalars
(``train/length`` in s, ``train/train_s``) are drawn against training minutes, the clock
both count (start-up and checkpoint writes left out). The episodes end by different rules:
MyoSuite's when the centre of mass drops below 0.8 m or the torso turns over, gaitforge's
imitation when the pose drifts 0.5 rad from the recording or the pelvis drops below 0.6 m;
read the curves as "how long the body stays up", not as one measure.

Run with the project's environment (matplotlib, tensorboard), not the anchors' venv.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from curriculum_run import run_scalars  # bench/curriculum_run.py

MYOSUITE_STEP_S = 0.01
"""Seconds of one myoLegWalk-v0 step (its frame skip times MuJoCo's timestep)."""


def anchor_curve(run: Path) -> tuple[list[float], list[float]]:
    """(training minutes, mean episode length in s) of an anchor run's progress rows that
    saw an episode end."""
    minutes, lengths = [], []
    with (run / "progress.csv").open() as rows:
        for row in csv.DictReader(rows):
            if int(row["episodes"]) > 0:
                minutes.append(float(row["wall_s"]) / 60.0)
                lengths.append(float(row["mean_length"]) * MYOSUITE_STEP_S)
    return minutes, lengths


def gaitforge_curve(run: Path) -> tuple[list[float], list[float]]:
    """(training minutes, mean episode length in s) of a gaitforge run, one point per update
    (by env steps, read by ``bench/curriculum_run.py``'s ``run_scalars``)."""
    scalars = run_scalars(run)
    seconds, lengths = scalars["train_s"], scalars["length"]
    steps = sorted(seconds.keys() & lengths.keys())
    return [seconds[step] / 60.0 for step in steps], [lengths[step] for step in steps]


def labelled(pairs: list[str], flag: str) -> list[tuple[str, Path]]:
    """``label=path`` arguments as (label, path); the error names ``flag``."""
    out = []
    for pair in pairs:
        label, sep, path = pair.partition("=")
        if not sep or not label or not path:
            raise SystemExit(f"{flag} {pair!r}: expected LABEL=PATH")
        out.append((label, Path(path)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--anchor", action="append", default=[], metavar="LABEL=RUN")
    parser.add_argument("--gaitforge", action="append", default=[], metavar="LABEL=RUN")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--title", default="MyoLeg: how long the body stays up while training")
    parser.add_argument("--minutes-label", default="training minutes (2 cores)")
    args = parser.parse_args()
    figure, axes = plt.subplots(figsize=(8, 4.5))
    for label, run in labelled(args.anchor, "--anchor"):
        axes.plot(*anchor_curve(run), label=f"{label} (myoLegWalk-v0)")
    for label, run in labelled(args.gaitforge, "--gaitforge"):
        axes.plot(*gaitforge_curve(run), label=f"{label} (gaitforge)")
    axes.set_xlabel(args.minutes_label)
    axes.set_ylabel("mean training episode length (s)")
    axes.set_title(args.title)
    axes.grid(alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(args.out, dpi=110)


if __name__ == "__main__":
    main()
