"""Curriculum runs' stages read off their scalars (``bench/curriculum_run.py``): where each
stage ended, the env steps and training minutes it took, its last evaluation, the median
over runs, on fixed data; the stage names from the newest checkpoint's job; and the curves'
PNG."""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from curriculum_run import Run, median_rows, plot_runs, stage_names, stage_rows  # noqa: E402

SCALARS = {
    "stage": {100: 0.0, 200: 0.0, 300: 1.0, 400: 1.0, 500: 2.0},
    "train_s": {100: 60.0, 200: 120.0, 300: 200.0, 400: 300.0, 500: 330.0},
    "return": {100: 1.0, 200: 2.0, 300: 0.5, 400: 1.5, 500: 2.5},
    "speed": {100: 0.1, 200: 0.2, 300: 0.3, 400: 0.4, 500: 0.5},
    "fall_rate": {100: 0.9, 200: 0.8, 300: 0.5, 400: 0.3, 500: 0.2},
    "eval_speed": {300: 0.9, 400: 1.1},
    "eval_fall_rate": {300: 0.2, 400: 0.08},
}


def test_each_stage_ends_where_the_next_begins() -> None:
    rows = stage_rows(SCALARS)
    assert [r["stage"] for r in rows] == [0, 1, 2]
    assert [(r["env_steps"], r["stage_env_steps"]) for r in rows] == [
        (200, 200),
        (400, 200),
        (500, 100),
    ]
    assert [r["stage_s"] for r in rows] == [120.0, 180.0, 30.0]
    assert rows[1]["eval_fall_rate"] == 0.08 and rows[1]["eval_speed"] == 1.1
    assert "eval_speed" not in rows[0]


def test_the_stage_names_come_from_the_newest_checkpoint(tmp_path: Path) -> None:
    assert stage_names(tmp_path) == []
    for steps, names in ((100, ["old"]), (500, ["walk", "run", "obstacles"])):
        checkpoint = tmp_path / "checkpoints" / f"ckpt-{steps:012d}"
        checkpoint.mkdir(parents=True)
        job = {"stages": [{"name": name} for name in names]}
        (checkpoint / "meta.json").write_text(json.dumps({"job": job}))
        (checkpoint / "manifest.json").write_text("{}")  # written last: the checkpoint is complete
    assert stage_names(tmp_path) == ["walk", "run", "obstacles"]


NAMES = ["walk", "run", "obstacles"]


def slower(scalars: dict[str, dict[int, float]], factor: float) -> dict[str, dict[int, float]]:
    """The same run with every training second ``factor`` times longer."""
    return {**scalars, "train_s": {k: v * factor for k, v in scalars["train_s"].items()}}


def test_the_median_over_runs_is_taken_per_stage() -> None:
    scaled = [slower(SCALARS, factor) for factor in (1.0, 3.0, 2.0)]
    runs = [Run(f"seed-{i}", s, stage_rows(s), NAMES) for i, s in enumerate(scaled)]
    runs[2].rows.pop()  # a run that has not reached the last stage
    medians = median_rows(runs)
    assert [m["stage"] for m in medians] == [0, 1]
    assert [m["stage_s"] for m in medians] == [240.0, 360.0]
    assert [m["train_s"] for m in medians] == [240.0, 600.0]
    assert [m["stage_env_steps"] for m in medians] == [200, 200]


def test_the_curves_are_written(tmp_path: Path) -> None:
    one = Run("seed-0", SCALARS, stage_rows(SCALARS), NAMES)
    assert one.stage_name(2) == "obstacles" and one.stage_name(3) == ""
    for runs, name in (([one], "one.png"), ([one, one], "two.png")):
        plot_runs(runs, tmp_path / name)
        assert (tmp_path / name).stat().st_size > 10_000
