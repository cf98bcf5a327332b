"""bench/relaxed_drop.py: the relaxed body let go on MuJoCo (two contact time constants) and
OpenSim from the same reset, a table of the right foot's depths and force, ankle, knee and
pelvis (real simulators, 0.03 s)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench


def test_the_relaxed_drop_gives_a_table_and_series_per_variant(
    tmp_path: Path, run_bench: RunBench
) -> None:
    out = tmp_path / "drop.json"
    done = run_bench(
        "relaxed_drop.py",
        "--scene",
        "walk-2d+clock",
        "--timeconst",
        "0.02",
        "0.12",
        "--every-s",
        "0.01",
        "--until-s",
        "0.03",
        "--json-out",
        str(out),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "mujoco 0.12 s" in done.stdout and "opensim" in done.stdout
    data = json.loads(out.read_text())
    assert set(data["runs"]) == {"mujoco 0.02 s", "mujoco 0.12 s", "opensim"}
    for rows in data["runs"].values():
        assert len(rows) == 3 and all(len(r) == len(data["series"]) for r in rows)
        heel, toe = rows[-1][0], rows[-1][1]
        assert toe < 0.0 < heel  # reset on the toe, heel up: the toe takes the load


def test_bad_arguments_are_refused_with_the_argument_named(run_bench: RunBench) -> None:
    done = run_bench("relaxed_drop.py", "--excitation", "2", timeout_s=120)
    assert done.returncode != 0 and "--excitation" in done.stderr
