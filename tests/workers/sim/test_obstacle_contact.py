"""Obstacles on MuJoCo are solid wherever a reset puts them, not only where the model was
compiled: a standing body over 10 spheres placed together along the course touches every
one of them from the first step.

The spheres are world geoms moved at every reset; MuJoCo's midphase walked the world body's
bounding volume tree from compile time, built with the spheres parked 100 m behind the start,
in which the branch holding the six farthest spheres lay there: their pairs with the feet
were dropped, and the feet went through them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator

FEET = {"r_heel", "r_toe", "l_heel", "l_toe"}


def _spheres_at(ahead_m: float) -> Scene:
    """obstacles-2d with its 10 spheres, 10 cm each, centred half a radius above the ground
    (their tops 15 cm up) ``ahead_m`` (m) from the start."""
    scene = load_scene("obstacles-2d").model_dump()
    scene["obstacles"].update(
        x_range=(ahead_m, ahead_m), radius_range=(0.1, 0.1), height_range=(0.5, 0.5)
    )
    return Scene.model_validate(scene)


def _touched_after_one_step(spheres_m: float, body_m: float) -> set[str]:
    """The obstacles in MuJoCo's contacts with a foot after one 10-ms step of the standing
    body moved ``body_m`` forward and 10 cm up, spheres ``spheres_m`` from the start."""
    sim = make_simulator(_spheres_at(spheres_m), "mujoco")
    sim.reset(0)
    m, d = sim.model, sim.data
    d.qpos[sim._root_slide_along(sim.forward_axis)] += body_m
    d.qpos[sim._root_slide_along(sim.up_axis)] += 0.1
    mujoco.mj_forward(m, d)
    assert sim.step(np.full(len(sim.muscle_names), 0.3), 0.01).ok
    pairs = [
        {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in c.geom}
        for c in d.contact[: d.ncon]
    ]
    return {n for pair in pairs if pair & FEET for n in pair if n.startswith("obstacle_")}


@pytest.mark.parametrize("ahead_m", [0.0, 5.0, 9.5])
def test_spheres_under_the_feet_touch_them_anywhere_along_the_course(ahead_m: float) -> None:
    assert _touched_after_one_step(ahead_m, ahead_m) == {f"obstacle_{i}" for i in range(10)}
    assert not _touched_after_one_step(ahead_m + 1.0, ahead_m), "a metre ahead: untouched"
