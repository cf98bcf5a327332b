"""bench/sweep_falls.py: falls per sweep point, per run, median and pooled, counted on fixed
reports (two runs of a two-point sweep with known falls), so that what is tested is the
counting and never whether an episode of a learned policy falls on this machine."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from conftest import RunBench

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from sweep_falls import fallen_episodes_table, falls_table, sweep_points  # noqa: E402

EPISODES = 4
TARGETS = (3.0, 2.1)


def sweep_report(fell_at: dict[float, list[int]], speed_m_s: dict[float, float]) -> dict:
    """A sweep report as ``gaitforge evaluate --sweep --json-out`` writes it, of ``EPISODES``
    episodes (seeds 0..3) per target speed; ``fell_at[target]`` lists the seeds that fell."""
    points = []
    for target in TARGETS:
        episodes = [
            {
                "seed": seed,
                "fell": seed in fell_at[target],
                "time_s": 2.5 + seed,
                "distance_m": 7.0 + seed,
                "first_obstacle_touch_s": None,
            }
            for seed in range(EPISODES)
        ]
        falls = len(fell_at[target])
        result = {
            "episodes": episodes,
            "fall_rate": {"value": falls / EPISODES, "count": falls, "n": EPISODES},
            "mean_speed_m_s": {"mean": speed_m_s[target]},
        }
        points.append({"target_speed_m_s": target, "result": result})
    return {"checkpoint": "ckpt", "sweep": points}


RUN_A = sweep_report({3.0: [1, 2], 2.1: []}, {3.0: 2.61, 2.1: 1.92})
RUN_B = sweep_report({3.0: [0, 1, 3], 2.1: [2]}, {3.0: 2.55, 2.1: 1.88})
RUN_C = sweep_report({3.0: [3], 2.1: [0]}, {3.0: 2.58, 2.1: 1.90})


def rows(table: Any) -> dict[str, list[str]]:
    """A rich table's rows by their first cell: {label: [the other cells]}."""
    columns = [list(column.cells) for column in table.columns]
    return {cells[0]: list(cells[1:]) for cells in zip(*columns, strict=True)}


def test_falls_are_counted_per_run_with_the_median_and_the_pool() -> None:
    runs = [sweep_points(report) for report in (RUN_A, RUN_B, RUN_C)]
    table = rows(falls_table(runs, ["a", "b", "c"]))
    assert table["a"] == ["2 (2.61 m/s)", "0 (1.92 m/s)"]
    assert table["b"] == ["3 (2.55 m/s)", "1 (1.88 m/s)"]
    assert table["c"] == ["1 (2.58 m/s)", "1 (1.90 m/s)"]
    assert table["median of 3"] == ["2", "1"]
    assert table["all (of 12)"] == ["6 (50.0 %)", "2 (16.7 %)"]


def test_the_falls_at_chosen_points_list_each_fallen_episode() -> None:
    runs = [sweep_points(report) for report in (RUN_A, RUN_B)]
    table = fallen_episodes_table(runs, ["a", "b"], [2.1])
    seeds = [list(column.cells) for column in table.columns][2]
    assert seeds == ["2"]  # only run b fell at 2.1, in episode 2


def test_the_script_prints_the_table_and_writes_the_plot(
    run_bench: RunBench, tmp_path: Path
) -> None:
    paths = []
    for name, report in (("a", RUN_A), ("b", RUN_B)):
        paths.append(tmp_path / f"{name}.json")
        paths[-1].write_text(json.dumps(report))
    png = tmp_path / "falls.png"
    arguments = [*map(str, paths), "--episodes-at", "3.0", "--out", str(png)]
    result = run_bench("sweep_falls.py", *arguments)
    assert result.returncode == 0, result.stderr
    assert "median of 2" in result.stdout and "all (of 8)" in result.stdout
    assert "Episodes that fell" in result.stdout
    assert png.stat().st_size > 0


def test_a_report_without_a_sweep_is_refused(tmp_path: Path, run_bench: RunBench) -> None:
    report = tmp_path / "eval.json"
    report.write_text(json.dumps({"checkpoint": "ckpt", "sweep": []}))
    result = run_bench("sweep_falls.py", str(report))
    assert result.returncode != 0 and "not a sweep" in result.stderr
