"""bench/replay_turn.py: a clock scene's recording replayed with no policy, the body's turn
about the vertical in each variant (real MuJoCo)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench


def test_a_planar_replay_never_turns_and_a_3d_one_does(run_bench: RunBench) -> None:
    planar = run_bench("replay_turn.py", "--scene", "walk-2d+clock", "--episodes", "1")
    assert planar.returncode == 0, planar.stderr
    rows = [line for line in planar.stdout.splitlines() if line.startswith("│")]
    assert len(rows) == 4  # as it is, three contact settings
    assert all(cells.split("│")[-2].strip() == "0-0" for cells in rows)
    myoleg = run_bench("replay_turn.py", "--scene", "walk-3d+clock", "--episodes", "2")
    assert myoleg.returncode == 0, myoleg.stderr
    first = next(line for line in myoleg.stdout.splitlines() if "as the scene is" in line)
    assert int(first.split("│")[5]) > 5  # the replay turns MyoLeg by tens of degrees
