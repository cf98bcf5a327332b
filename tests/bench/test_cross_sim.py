"""bench/cross_sim.py: the shipped walker on MuJoCo and OpenSim from the same seeds, a table,
a plot and the medians per step (real simulators; episodes cut at 1 s)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench

REPO = Path(__file__).resolve().parents[2]


def test_the_walker_on_both_simulators_gives_a_table_a_plot_and_medians(
    tmp_path: Path, run_bench: RunBench
) -> None:
    out = tmp_path / "cross.png"
    scene = tmp_path / "short.yaml"
    scene.write_text(
        "name: short\nbase: walk-2d\noptions: [clock]\nset: {episode_s: 1.0}\n"
    )  # walk-2d+clock, 1-s episodes
    done = run_bench(
        "cross_sim.py",
        str(REPO / "examples/policies/walk-2d"),
        "--scene",
        str(scene),
        "--episodes",
        "2",
        "--every-s",
        "0.4",
        "--out",
        str(out),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "mu height m" in done.stdout and "op height m" in done.stdout
    assert "knee_angle_r" in done.stdout  # the joint-angle table
    for png in (out, tmp_path / "cross-joints.png", tmp_path / "cross-muscles.png"):
        assert png.stat().st_size > 10_000, png
    medians = json.loads(out.with_suffix(".json").read_text())
    for backend in ("mujoco", "opensim"):
        data = medians[backend]
        series = data["series"]
        assert series[:5] == ["height", "forward", "pitch", "foot_r", "foot_l"]
        joints = [n for n in series if n.startswith("q:")]
        muscles = [n for n in series if n.startswith("a:")]
        assert len(joints) == 6 and "q:ankle_angle_l" in joints
        assert len(muscles) == 18 and "a:soleus_r" in muscles
        assert data["episodes_up"][0] == 2 and len(data["median"]) == 25  # 1 s at 25 Hz
        first = dict(zip(series, data["median"][0], strict=True))
        assert 0.8 < first["height"] < 1.0, (backend, first["height"])
        assert all(0.0 <= first[m] <= 1.0 for m in muscles), (backend, first)
        assert abs(first["q:knee_angle_r"]) < 1.5, (backend, first)  # rad, a standing start
