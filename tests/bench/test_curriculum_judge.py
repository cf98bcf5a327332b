"""Curriculum runs judged stage by stage (``bench/curriculum_judge.py``): which stages are
judged, read off the run's job, and the table's cells and medians on fixed figures."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from curriculum_judge import cell, judged_stages, median_cell, table  # noqa: E402


def run_with_job(root: Path, stages: list[dict]) -> Path:
    """A run folder whose one checkpoint's ``meta.json`` holds a job of ``stages``."""
    checkpoint = root / "checkpoints" / "ckpt-000000001000"
    checkpoint.mkdir(parents=True)
    (checkpoint / "meta.json").write_text(json.dumps({"job": {"stages": stages}}))
    (checkpoint / "manifest.json").write_text("{}")  # written last: the checkpoint is complete
    return root


def test_the_stages_with_promotion_rules_are_judged_on_their_scenes(tmp_path: Path) -> None:
    run = run_with_job(
        tmp_path,
        [
            {"name": "imitate", "scene": "imitate-walk-2d+standing-starts"},
            {"name": "walk", "scene": "walk-2d+clock", "promote": ["eval.speed >= 1"]},
            {"scene": "run-2d+clock", "promote": ["eval.fall_rate <= 0.1"]},
        ],
    )
    assert judged_stages(run) == [(1, "walk", "walk-2d+clock"), (2, "stage-2", "run-2d+clock")]


def test_a_run_without_checkpoints_is_refused(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="no checkpoints"):
        judged_stages(tmp_path)


def judged(falls: int, speed: float, sweep: list[int] | None = None) -> dict:
    figures = {"falls": falls, "episodes": 100, "speed_m_s": speed}
    if sweep is not None:
        figures["sweep"] = [
            {"target_m_s": target, "falls": f, "episodes": 300, "speed_m_s": target - 0.4}
            for target, f in zip((3.0, 2.7, 2.4, 2.1), sweep, strict=True)
        ]
    return figures


def test_cells_say_falls_speed_and_the_sweep() -> None:
    assert cell(None) == "-"
    assert cell(judged(6, 2.935)) == "6 % at 2.94 m/s"
    assert cell(judged(1, 2.25, [16, 7, 5, 4])) == "1 % at 2.25 m/s; sweep 16 / 7 / 5 / 4 of 300"


def test_the_median_is_taken_per_figure_and_per_sweep_point() -> None:
    runs = [
        judged(6, 2.94, [16, 7, 5, 4]),
        judged(10, 3.10, [9, 2, 1, 0]),
        judged(2, 3.0, [20, 8, 2, 2]),
    ]
    assert median_cell(runs) == "6 % at 3.00 m/s; sweep 16 / 7 / 2 / 2"
    assert median_cell([judged(5, 3.0), judged(10, 3.2)]) == "7.5 % at 3.10 m/s"
    assert median_cell([]) == "-"


def test_a_share_of_300_episodes_keeps_one_decimal() -> None:
    two_of_300 = {"falls": 2, "episodes": 300, "speed_m_s": 2.23}
    assert cell(two_of_300) == "0.7 % at 2.23 m/s"
    assert median_cell([two_of_300]) == "0.7 % at 2.23 m/s"


def test_the_table_has_a_row_per_stage_and_a_column_per_run() -> None:
    out = table(
        {
            "seed-0": {"walk": judged(0, 1.18)},
            "seed-1": {"walk": judged(4, 1.2), "run": judged(6, 3.0)},
        }
    )
    assert [column.header for column in out.columns] == ["stage", "seed-0", "seed-1", "median of 2"]
    assert out.row_count == 2
