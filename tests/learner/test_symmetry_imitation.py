"""Mirror augmentation in an imitation scene: the phase stays, ``phase_mirror`` flips."""

from __future__ import annotations

import torch
from gaitforge.learner.symmetry import MirrorMap
from gaitforge.workers.env import MuscleEnv


def test_the_mirror_image_of_an_imitation_observation_flips_phase_mirror_only() -> None:
    env = MuscleEnv("imitate-walk-2d")
    mirror = MirrorMap.from_names(env.obs_names, env.sim.muscle_names, lateral_axis=2)
    obs, _ = env.reset(seed=1)
    image = mirror.obs(torch.from_numpy(obs[None]))[0].numpy()
    names = env.obs_names
    for name in ("phase_sin", "phase_cos", "phase_mirror"):
        sign = -1.0 if name == "phase_mirror" else 1.0
        assert image[names.index(name)] == sign * obs[names.index(name)]
