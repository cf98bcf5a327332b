"""The committed topology of MyoSuite's bodies is what the installed myo-sim model gives
(as ``bench/data/mjcf_topology.py`` writes it), and loading a scene reads it without importing
a simulator."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from gaitforge.workers.bodies.topology import MJCF_BODIES, topology_file, topology_for

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "bench" / "data"))

from mjcf_topology import mjcf_topology, topology_yaml  # noqa: E402


@pytest.mark.parametrize("body", MJCF_BODIES)
def test_committed_topology_matches_the_model(body: str) -> None:
    assert topology_file(body).read_text() == topology_yaml(body), (
        f"{topology_file(body)} is stale for the installed myo-sim; rewrite it with "
        "python bench/data/mjcf_topology.py --write"
    )
    loaded, live = topology_for(body), mjcf_topology(body)
    assert loaded == live
    assert list(loaded.dof_defaults) == list(live.dof_defaults)  # order is observation order
    assert list(loaded.muscle_spans) == list(live.muscle_spans)


def test_loading_scenes_needs_no_simulator() -> None:
    code = (
        "import sys\n"
        "from gaitforge.workers.scenes import catalogue, load_scene\n"
        "for name in catalogue():\n"
        "    load_scene(name)\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'mujoco', 'opensim', 'ray'}))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
