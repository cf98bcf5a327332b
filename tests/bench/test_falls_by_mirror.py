"""bench/falls_by_mirror.py: a real evaluation's episodes split by the clock's mirroring."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from falls_by_mirror import mirrored_by_seed, split  # noqa: E402


def test_the_shipped_walkers_episodes_split_by_their_resets_mirroring(tmp_path: Path) -> None:
    """8 deterministic walk-2d+clock episodes (its clock mirrored half the time): each side
    has the episodes whose reset mirrored, with their own falls and speeds."""
    report_path = tmp_path / "eval.json"
    subprocess.run(
        [sys.executable, "-m", "gaitforge.service.cli", "evaluate",
         str(REPO / "examples/policies/walk-2d"), "--scene", "walk-2d+clock", "--episodes", "8",
         "--seed", "3", "--json-out", str(report_path)],
        check=True, capture_output=True, timeout=600,
    )  # fmt: skip
    report = json.loads(report_path.read_text())
    episodes = report["results"]["deterministic"]["episodes"]
    mirrored = mirrored_by_seed("walk-2d+clock", list(range(3, 11)))
    assert set(mirrored.values()) == {True, False}, "both sides among 8 resets"
    parts = split(report, "walk-2d+clock")
    for name, side in (("mirrored", True), ("not mirrored", False)):
        mine = [e for e in episodes if mirrored[e["seed"]] is side]
        assert parts[name]["episodes"] == len(mine)
        assert parts[name]["fall_rate"] == sum(e["fell"] for e in mine) / len(mine)
        assert parts[name]["speed"] == pytest.approx(
            sum(e["mean_speed_m_s"] for e in mine) / len(mine)
        )
        assert 0.5 < parts[name]["speed"] < 2.0, "the walker walks on both sides"


def test_a_scene_without_a_clock_is_refused() -> None:
    with pytest.raises(SystemExit, match="no imitation clock"):
        mirrored_by_seed("walk-2d", [0])
