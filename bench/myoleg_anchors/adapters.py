"""Adapters that let deprl 0.5.0 (written for MyoSuite 2, gym and numpy 1) train on MyoSuite 3.

deprl drives ``myoLegWalk-v0`` through its own wrappers (``GymWrapper``, ``Sequential``,
``Parallel``, ``test_mujoco``) that expect the MyoSuite 2 / gym 0.x surface. MyoSuite 3 is
Gymnasium-native: other wrapper chain, other action space, no ``sim`` object. Each adapter
below bridges one such gap and says why it is needed; none changes DEP-RL's algorithm or its
published hyperparameters.

``install()`` applies the process-wide ones. It must run in every process that builds a deprl
environment, including the worker processes that deprl's ``Parallel`` starts with ``spawn``:
``deprl_walk.py`` appends ``import adapters; adapters.install()`` to the config's ``header``,
which deprl executes in each worker before it builds environments.

Action mapping (MyoSuite 2's, which MyoSuite 3 dropped): MyoSuite 2 exposed ``[-1, 1]`` actions
for muscle models and turned them into activations with ``1 / (1 + exp(-5 (a - 0.5)))``;
DEP-RL's policy and DEP controller both emit ``[-1, 1]``. MyoSuite 3's ``myoLegWalk-v0``
takes activations in ``[0, 1]`` as they are, so :func:`myosuite2_activation` restores the old
map (activations then lie in about [0.0006, 0.92], as under MyoSuite 2).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np

log = logging.getLogger(__name__)

#: MyoSuite 2's slope of the sigmoid from a [-1, 1] action to a muscle activation (1).
SIGMOID_SLOPE = 5.0
#: MyoSuite 2's centre of that sigmoid (1).
SIGMOID_CENTRE = 0.5

_installed = False


def myosuite2_activation(action: np.ndarray) -> np.ndarray:
    """MyoSuite 2's map from a normalised action to muscle activations.

    Args:
        action: actions in [-1, 1] (values outside are clipped first, as MyoSuite 2 did), (1).

    Returns:
        activations in (0, 1), (1), float64.
    """
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    return 1.0 / (1.0 + np.exp(-SIGMOID_SLOPE * (a - SIGMOID_CENTRE)))


class MyoSuite2Actions(gym.ActionWrapper):
    """Show a ``[-1, 1]`` action space and apply MyoSuite 2's sigmoid to reach ``[0, 1]``.

    Why: deprl's config builds the env with ``scaled_actions=False`` because MyoSuite 2's
    action space already was ``[-1, 1]``; its DEP controller and MPO policy output that range.
    Fed to MyoSuite 3 directly, every negative action would be clipped to 0.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        n = env.action_space.shape[0]
        self.action_space = gym.spaces.Box(-1.0, 1.0, (n,), dtype=np.float32)

    def action(self, action: np.ndarray) -> np.ndarray:
        """Activations (1) for the env from a [-1, 1] action (1)."""
        return myosuite2_activation(action)


def _strip_time_limit(env: gym.Env) -> gym.Env:
    """Remove the ``TimeLimit`` that MyoSuite 3 hides under its outermost wrapper.

    Why: deprl's builder drops gym's ``TimeLimit`` so that a timeout is a reset, not a
    termination (its ``Sequential`` resets at ``max_episode_steps`` itself). It only looks at
    the outermost wrapper; MyoSuite 3 puts ``MjInstabilityTerminationWrapper`` on top, so the
    ``TimeLimit`` would survive and every 1000-step timeout would be stored as a terminal
    transition (no bootstrap) in the replay.
    """
    outer = env
    while isinstance(outer, gym.Wrapper):
        inner = outer.env
        if isinstance(inner, gym.wrappers.TimeLimit):
            outer.env = inner.env
            return env
        outer = inner
    return env


def make_myosuite3_env(name: str, *args: Any, **kwargs: Any) -> gym.Env:
    """``gym.make(name, ...)`` made to look like a MyoSuite 2 env to deprl.

    Besides :class:`MyoSuite2Actions` and :func:`_strip_time_limit`, it sets two attributes
    that deprl reads on ``env.unwrapped``:

    - ``horizon``: the episode length in steps (1000). Why: deprl's
      ``GymWrapper._max_episode_steps`` reads ``unwrapped.max_episode_steps`` or
      ``unwrapped.horizon`` (MyoSuite 2 had the latter); MyoSuite 3 keeps it only in the
      spec. The returned wrapper's ``_max_episode_steps`` carries it too, for deprl's builder
      (which otherwise assumes 1000 because the ``TimeLimit`` is no longer outermost).
    - ``sim``: an object with ``model`` and ``data`` (the ``MjModel``/``MjData``). Why: deprl
      reads the DEP input (``sim.data.actuator_length``, ``actuator_force``) and its test
      effort (``sim.model.na``, ``sim.data.act``) through MyoSuite 2's ``sim``; MyoSuite 3 has
      ``model``/``data`` directly. Both objects live as long as the env (reset is in place).

    Args:
        name: registered env id, e.g. ``"myoLegWalk-v0"``.
        *args: passed to ``gym.make``.
        **kwargs: passed to ``gym.make`` (e.g. ``reset_type="random"``).

    Returns:
        the adapted env.
    """
    env = gym.make(name, *args, **kwargs)
    horizon = env.spec.max_episode_steps if env.spec is not None else None
    env = _strip_time_limit(env)
    base = env.unwrapped
    base.horizon = int(horizon) if horizon else 1000
    base.sim = SimpleNamespace(model=base.model, data=base.data)
    wrapped = MyoSuite2Actions(env)
    wrapped._max_episode_steps = base.horizon  # where deprl's builder looks first
    return wrapped


def myosuite3_gym_environment(*args: Any, **kwargs: Any) -> gym.Env:
    """Drop-in for ``deprl.environments.Gym`` that builds through :func:`make_myosuite3_env`.

    Why: the published config names ``deprl.environments.Gym('myoLegWalk-v0', ...)``; replacing
    the function it resolves to keeps that string as published. deprl's own
    ``build_environment`` still does the rest (time limit, action rescaling, name).
    """
    from deprl.vendor.tonic.environments import builders

    kwargs.pop("header", None)
    return builders.build_environment(make_myosuite3_env, *args, **kwargs, header=None)


def _forward_public_attribute(self: gym.Wrapper, name: str) -> Any:
    """``__getattr__`` for deprl's wrappers: public names come from the wrapped env.

    Why: gym 0.x wrappers forwarded unknown attributes to the inner env, Gymnasium 1.x
    wrappers do not. deprl calls ``env.seed(...)`` and reads ``env.name`` on its
    ``GymWrapper`` and ``env.sim`` in its test loop; without this they raise
    ``AttributeError``. Private names are not forwarded (as in MyoSuite's own forwarding).
    """
    if name.startswith("_") or name == "env":
        raise AttributeError(name)
    return self.env.get_wrapper_attr(name)


class _IntableFlags(np.ndarray):
    """A 1-element bool array that ``int()`` accepts (NumPy 2 raises for ndim > 0)."""

    def __int__(self) -> int:
        return int(self.reshape(-1)[0])


class TestEnvironment:
    """Proxy for deprl's one-env test ``Sequential`` whose ``terminations`` ``int()`` accepts.

    Why: ``deprl.custom_test_environment.test_mujoco`` does ``int(info["terminations"])`` on
    a shape-(1,) array, which NumPy 2 rejects (``TypeError: only 0-dimensional arrays can be
    converted to Python scalars``). Everything else is forwarded unchanged.
    """

    def __init__(self, environment: Any) -> None:
        self.__dict__["_environment"] = environment

    def __getattr__(self, name: str) -> Any:
        return getattr(self.__dict__["_environment"], name)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        """Step the wrapped environments; see the class docstring."""
        observations, muscle_states, infos = self.__dict__["_environment"].step(actions)
        infos["terminations"] = np.asarray(infos["terminations"]).view(_IntableFlags)
        return observations, muscle_states, infos


def install() -> None:
    """Apply the process-wide adapters (idempotent).

    - ``GymWrapper.__getattr__``: see :func:`_forward_public_attribute`.
    - ``deprl.environments.Gym``: see :func:`myosuite3_gym_environment`.
    - ``TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD=1``. Why: torch >= 2.6 loads with
      ``weights_only=True`` by default; deprl's checkpoints hold NumPy arrays (replay buffer,
      observation normaliser) and sets (logger), so resuming would fail. deprl catches that
      failure and continues with an empty normaliser state and a replay whose counters are
      restored but whose contents are NaN. The files are the run's own.
    """
    global _installed
    if _installed:
        return
    os.environ.setdefault("TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD", "1")
    from deprl.env_wrappers.gym_wrapper import GymWrapper
    from deprl.vendor.tonic import environments

    GymWrapper.__getattr__ = _forward_public_attribute
    gym_builder: Callable[..., gym.Env] = myosuite3_gym_environment
    environments.Gym = gym_builder
    environments.builders.Gym = gym_builder
    _installed = True
    log.debug("deprl adapters for MyoSuite 3 installed")
