"""bench/cross_sim.py: the shipped walker on MuJoCo and OpenSim from the same seeds, a table,
a plot and the medians per step (real simulators; episodes cut at 1 s)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_the_walker_on_both_simulators_gives_a_table_a_plot_and_medians(tmp_path: Path) -> None:
    out = tmp_path / "cross.png"
    scene = tmp_path / "short.yaml"
    walk = (REPO / "workers/scenes/catalogue/walk-2d-clock.yaml").read_text()
    scene.write_text(
        walk.replace("name: walk-2d-clock", "name: short").replace(
            "episode_s: 10", "episode_s: 1.0"
        )
    )
    done = subprocess.run(
        [sys.executable, str(REPO / "bench/cross_sim.py"), str(REPO / "examples/policies/walk-2d"),
         "--scene", str(scene), "--episodes", "2", "--every-s", "0.4", "--out", str(out)],
        capture_output=True, text=True, timeout=300, env={**os.environ, "COLUMNS": "200"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "mu height m" in done.stdout and "op height m" in done.stdout
    assert out.stat().st_size > 10_000
    medians = json.loads(out.with_suffix(".json").read_text())
    for backend in ("mujoco", "opensim"):
        data = medians[backend]
        assert data["series"] == ["height", "forward", "pitch", "foot_r", "foot_l"]
        assert data["episodes_up"][0] == 2 and len(data["median"]) == 25  # 1 s at 25 Hz
        height = data["median"][0][0]
        assert 0.8 < height < 1.0, (backend, height)
