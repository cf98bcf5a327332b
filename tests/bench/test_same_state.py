"""bench/same_state.py: MuJoCo put in OpenSim's state (relaxed 0.02 s after the reset, or
driven by a policy); the two simulators' mass matrices agree, and the tables give both
accelerations, MuJoCo's with OpenSim's contact forces, the generalized force left, both
muscle moments and each body's contact force on both (real simulators)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

if TYPE_CHECKING:
    from conftest import RunBench

REPO = Path(__file__).resolve().parents[2]
PRINTED_FORCE_TOL = 0.011
"""body weights: the contact table prints forces to 0.01; two simulators' forces (each their
own code, in a state that differs between machines) that agree far more closely can still
round to neighbouring hundredths"""


def test_the_same_state_on_both_simulators_gives_the_table(run_bench: RunBench) -> None:
    done = run_bench("same_state.py", "--at-s", "0.02", columns=250)
    assert done.returncode == 0, done.stderr[-2000:]
    gap = re.search(r"differ by at most ([0-9.e+-]+)", done.stdout)
    assert gap and float(gap.group(1)) < 1e-9, done.stdout[:400]
    for row in ("MuJoCo, OpenSim's contacts", "force left, N m", "muscles OpenSim, N m"):
        assert row in done.stdout


def test_under_the_walker_mujoco_on_opensims_laws_pushes_and_pulls_as_opensim(
    tmp_path: Path, run_bench: RunBench
) -> None:
    """OpenSim driven by the shipped walker for 0.2 s; MuJoCo, with its contact, limits and
    muscles on OpenSim's laws, given that state: both tables, each body's contact force and
    each joint's muscle moment the same."""
    scene = tmp_path / "laws.yaml"
    scene.write_text(
        "name: laws\nbase: walk-2d\noptions: [clock]\nset:\n"
        "  mujoco.contact_model: hunt-crossley\n  mujoco.joint_limits: opensim\n"
        "  mujoco.muscle_curves: opensim\n  mujoco.muscle_passive: opensim\n"
    )
    done = run_bench(
        "same_state.py",
        "--policy",
        str(REPO / "examples/policies/walk-2d"),
        "--at-s",
        "0.2",
        "--mujoco-scene",
        str(scene),
        columns=250,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "driven by" in done.stdout and "force left, N m" in done.stdout
    rows = re.findall(
        r"│ (calcn_[lr]|toes_[lr]) +│ +(\S+) │ +(\S+) │ +(\S+) │ +(\S+) │", done.stdout
    )
    assert len(rows) == 4, done.stdout[-3000:]
    loaded = 0.0
    for _, *cells in rows:
        opensim_forward, opensim_up, mujoco_forward, mujoco_up = map(float, cells)
        assert (opensim_forward, opensim_up) == pytest.approx(
            (mujoco_forward, mujoco_up), abs=PRINTED_FORCE_TOL
        )
        loaded += opensim_up
    assert loaded > 0.5  # body weights: the feet carry the body
    moments = {
        name: [float(v) for v in re.findall(r"[+-]\d+\.\d", row)]
        for name, row in re.findall(r"│ muscles (MuJoCo|OpenSim), N m +│(.*)", done.stdout)
    }
    assert len(moments["OpenSim"]) == 6, done.stdout[-3000:]
    assert np.abs(np.subtract(moments["MuJoCo"], moments["OpenSim"])).max() <= 0.3
