"""bench/sweep_falls.py: a real sweep's falls per point, per run, median and pooled."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from conftest import RunBench

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from sweep_falls import sweep_points  # noqa: E402


@pytest.fixture(scope="module")
def sweep_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shipped speed runner swept at 3.0 and 2.1 m/s over 3 deterministic episodes."""
    path = tmp_path_factory.mktemp("sweep") / "sweep.json"
    subprocess.run(
        [sys.executable, "-m", "gaitforge.service.cli", "evaluate",
         str(REPO / "examples/policies/obstacles-2d-speeds"), "--scene",
         "obstacles-2d-clock-overspeed", "--episodes", "3", "--seed", "0", "--sweep",
         "--sweep-percent", "0,30", "--json-out", str(path)],
        check=True, capture_output=True, timeout=600,
    )  # fmt: skip
    return path


def test_falls_per_point_are_counted_per_run_and_pooled(
    sweep_report: Path, run_bench: RunBench, tmp_path: Path
) -> None:
    """The same sweep given as two runs: each row and the median carry the report's falls
    at each point, the pooled row twice them of 6 episodes; the plot is written."""
    points = sweep_points(json.loads(sweep_report.read_text()))
    assert list(points) == [3.0, 2.1]
    falls = [points[t]["fall_rate"]["count"] for t in (3.0, 2.1)]
    fell = [sum(e["fell"] for e in points[t]["episodes"]) for t in (3.0, 2.1)]
    assert falls == fell
    png = tmp_path / "falls.png"
    result = run_bench("sweep_falls.py", str(sweep_report), str(sweep_report),
                       "--labels", "a", "b", "--episodes-at", "3.0", "--out", str(png))  # fmt: skip
    assert result.returncode == 0, result.stderr
    rows = {line.split("│")[1].strip(): line for line in result.stdout.splitlines()
            if line.startswith("│")}  # fmt: skip
    for label in ("a", "b", "median of 2"):
        cells = [c.strip().split(" ")[0] for c in rows[label].split("│")[2:4]]
        assert cells == [str(f) for f in falls], rows[label]
    pooled = [c.strip().split(" ")[0] for c in rows["all (of 6)"].split("│")[2:4]]
    assert pooled == [str(2 * f) for f in falls]
    assert png.stat().st_size > 0


def test_a_report_without_a_sweep_is_refused(tmp_path: Path, run_bench: RunBench) -> None:
    report = tmp_path / "eval.json"
    report.write_text(json.dumps({"checkpoint": "ckpt", "sweep": []}))
    result = run_bench("sweep_falls.py", str(report))
    assert result.returncode != 0 and "not a sweep" in result.stderr
