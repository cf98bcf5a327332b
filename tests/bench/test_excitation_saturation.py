"""bench/excitation_saturation.py: the shipped walker's excitations and actions recorded from
a time on (real MuJoCo, the reflex layer), summarised per muscle and dof."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))

from excitation_saturation import record  # noqa: E402


def test_every_reflex_update_after_the_time_is_recorded() -> None:
    """The walker walks 10 s, so from 9 s on: 25 steps at 25 Hz, 20 reflex updates each."""
    excitations, actions, muscles, dofs = record(
        REPO / "examples/policies/walk-2d", "walk-2d+clock", episodes=1, after_s=9.0
    )
    assert actions.shape == (25, len(dofs)) and len(dofs) == 6
    assert excitations.shape == (25 * 20, len(muscles)) and len(muscles) == 18
    assert excitations.min() >= 0.0 and excitations.max() <= 1.0
    assert 0.0 < (excitations > 0.99).mean() < 1.0


def test_a_scene_on_excitations_is_refused(tmp_path: Path, run_bench: RunBench) -> None:
    done = run_bench(
        "excitation_saturation.py", str(REPO / "examples/policies/walk-2d"), "--scene",
        "walk-2d", "--episodes", "1", "--json-out", str(tmp_path / "out.json"),
    )  # fmt: skip
    assert done.returncode != 0 and "not joint_targets" in done.stderr
    assert not (tmp_path / "out.json").exists()
