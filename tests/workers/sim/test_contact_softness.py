"""``contact_timeconst_s`` on MuJoCo: a softer contact lets a standing body sink deeper; a
range draws a time constant per episode from the reset seed, and a pickled simulator goes
on with the one it drew; bad values are one-line errors naming the field."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from pydantic import ValidationError


def _stand(timeconst) -> Scene:
    scene = load_scene("stand-2d")
    return Scene.model_validate({**scene.model_dump(), "contact_timeconst_s": timeconst})


def _height_after(sim, seconds: float) -> float:
    for _ in range(round(seconds / 0.01)):
        assert sim.step(np.full(len(sim.muscle_names), 0.3), 0.01).ok
    return float(sim.state().pelvis_pos[sim.up_axis])


def test_a_softer_contact_sinks_deeper_and_a_range_is_drawn_per_episode() -> None:
    heights = {}
    for timeconst in (None, 0.12):
        sim = make_simulator(_stand(timeconst), "mujoco")
        sim.reset(0)
        heights[timeconst] = _height_after(sim, 0.1)
    assert heights[0.12] < heights[None] - 0.005, heights

    sim = make_simulator(_stand([0.05, 0.15]), "mujoco")
    drawn = []
    for seed in (0, 1, 0):
        sim.reset(seed)
        drawn.append(float(sim.model.geom_solref[0, 0]))
    assert all(0.05 <= t <= 0.15 for t in drawn) and drawn[0] == drawn[2] != drawn[1]

    sim.reset(1)
    _height_after(sim, 0.05)
    copy = pickle.loads(pickle.dumps(sim))
    # exactly: the same draw and the same steps in this process, so the same bits
    assert copy.model.geom_solref[0, 0] == drawn[1]
    assert _height_after(copy, 0.1) == _height_after(sim, 0.1)


@pytest.mark.parametrize("bad", [0.0, 2.0, [0.1, 0.05], "soft"])
def test_bad_contact_timeconsts_name_the_field(bad) -> None:
    with pytest.raises(ValidationError, match="contact_timeconst_s"):
        _stand(bad)
