"""bench/relaxed_drop.py: the relaxed body let go on MuJoCo (two contact time constants) and
OpenSim from the same reset, a table of the right foot's depths and force, ankle, knee and
pelvis (real simulators, 0.03 s)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_the_relaxed_drop_gives_a_table_and_series_per_variant(tmp_path: Path) -> None:
    out = tmp_path / "drop.json"
    done = subprocess.run(
        [sys.executable, str(REPO / "bench/relaxed_drop.py"), "--scene", "walk-2d-clock",
         "--timeconst", "0.02", "0.12", "--every-s", "0.01", "--until-s", "0.03",
         "--json-out", str(out)],
        capture_output=True, text=True, timeout=300, env={**os.environ, "COLUMNS": "200"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "mujoco 0.12 s" in done.stdout and "opensim" in done.stdout
    data = json.loads(out.read_text())
    assert set(data["runs"]) == {"mujoco 0.02 s", "mujoco 0.12 s", "opensim"}
    for rows in data["runs"].values():
        assert len(rows) == 3 and all(len(r) == len(data["series"]) for r in rows)
        heel, toe = rows[-1][0], rows[-1][1]
        assert toe < 0.0 < heel  # reset on the toe, heel up: the toe takes the load


def test_bad_arguments_are_refused_with_the_argument_named() -> None:
    done = subprocess.run(
        [sys.executable, str(REPO / "bench/relaxed_drop.py"), "--excitation", "2"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0 and "--excitation" in done.stderr
