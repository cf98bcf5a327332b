"""Observation and action names from the scene alone equal the built env's, for every
catalogue scene on every backend (the pruning plan's dofs, feet and muscles are those the
simulator built), and the env reads as many values for each part of the observation table
as the part has names; asking needs no simulator."""

from __future__ import annotations

import subprocess
import sys

import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import catalogue, load_scene
from gaitforge.workers.scenes.io_names import (
    OBSERVATION,
    action_names,
    lateral_axis,
    observation_names,
    world_axes,
)
from gaitforge.workers.scenes.migration import FORMER_NAMES

SCENES = catalogue() + sorted(set(FORMER_NAMES.values()))
CASES = [(name, backend) for name in SCENES for backend in load_scene(name).backends]


@pytest.mark.parametrize(("name", "backend"), CASES)
def test_names_equal_the_built_envs(name: str, backend: str) -> None:
    scene = load_scene(name)
    env = MuscleEnv(scene, backend)
    try:
        assert observation_names(scene, backend) == env.obs_names
        obs, _ = env.reset(seed=0)  # counts each part's values against its names
        assert obs.shape == (len(env.obs_names),)
        assert action_names(scene, backend) == env.act_names
        if not scene.action.targets:
            assert env.act_names == env.sim.muscle_names
        assert world_axes(scene.body) == (env.sim.up_axis, env.sim.forward_axis)
        assert lateral_axis(scene.body) == 3 - env.sim.up_axis - env.sim.forward_axis
    finally:
        env.close()


def test_each_part_has_its_own_key_and_names() -> None:
    keys = [entry.key for entry in OBSERVATION]
    assert len(set(keys)) == len(keys)
    for name in SCENES:
        scene = load_scene(name)
        for backend in scene.backends:
            names = observation_names(scene, backend)
            assert len(set(names)) == len(names), (name, backend)


def test_no_simulator_is_imported_to_ask() -> None:
    code = (
        "import sys\n"
        "from gaitforge.workers.scenes import catalogue, load_scene\n"
        "from gaitforge.workers.scenes.io_names import observation_names\n"
        "for name in catalogue():\n"
        "    scene = load_scene(name)\n"
        "    for backend in scene.backends:\n"
        "        assert observation_names(scene, backend)\n"
        "loaded = [m for m in ('mujoco', 'opensim') if m in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
