"""gaitforge: distributed PPO training for muscle-driven bodies on MuJoCo and OpenSim.

The Python face (this package is ``gaitforge`` itself; its parts are ``gaitforge.service``,
``gaitforge.learner`` and ``gaitforge.workers``)::

    import gaitforge
    import gymnasium as gym

    env = gym.make("gaitforge/walk-2d-v0")                       # a catalogue base scene
    env = gym.make("gaitforge/Scene-v0", scene="walk-2d+clock")  # any composition
    result = gaitforge.train("examples/elbow-reach.yaml", run_dir="runs/elbow", seed=1)
    report = gaitforge.evaluate(result.run_dir, episodes=10)
    policy = gaitforge.load_policy("examples/policies/walk-2d")  # obs -> action

Importing it registers the scenes with Gymnasium (``gaitforge.gym_env``); without the import,
``gym.make("gaitforge:gaitforge/walk-2d-v0")`` imports it first (Gymnasium 1.x has no
plugin entry points). Training, evaluation and the policy import torch when first called,
not here.
"""

from __future__ import annotations

from gaitforge.gym_registration import register_scenes
from gaitforge.python_face import TrainedPolicy, evaluate, load_policy, train

register_scenes()

__all__ = ["TrainedPolicy", "evaluate", "load_policy", "register_scenes", "train"]
