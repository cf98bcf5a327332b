"""bench/same_state.py: MuJoCo put in OpenSim's state (relaxed 0.02 s after the reset); the
two simulators' mass matrices agree, and the tables give both accelerations, MuJoCo's with
OpenSim's contact forces, the generalized force left, both muscle moments and each body's
contact force on both (real simulators)."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench


def test_the_same_state_on_both_simulators_gives_the_table(run_bench: RunBench) -> None:
    done = run_bench("same_state.py", "--at-s", "0.02", columns=250)
    assert done.returncode == 0, done.stderr[-2000:]
    gap = re.search(r"differ by at most ([0-9.e+-]+)", done.stdout)
    assert gap and float(gap.group(1)) < 1e-9, done.stdout[:400]
    for row in ("MuJoCo, OpenSim's contacts", "force left, N m", "muscles OpenSim, N m"):
        assert row in done.stdout
