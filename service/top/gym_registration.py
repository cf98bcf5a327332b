"""The scenes registered with Gymnasium under the ``gaitforge/`` namespace (``import
gaitforge`` runs :func:`register_scenes`).

- ``gaitforge/<base>-v0`` for each catalogue base scene (``gaitforge/walk-2d-v0``);
- ``gaitforge/Scene-v0`` for any scene, named by ``scene=``: a composition
  (``"run-2d+clock+one-leg"``, which a Gymnasium id cannot spell) or a scene YAML.

Each makes a ``gaitforge.gym_env.GymMuscleEnv``, which takes ``backend``, ``render_mode``
("rgb_array") and ``action_range`` ("unit", or "symmetric" for [-1, 1]). An episode ends
where its scene ends it (``truncated`` at ``episode_s``), so no time limit is added.
"""

from __future__ import annotations

from gaitforge.workers.scenes.compose import base_names

NAMESPACE = "gaitforge"
ENTRY_POINT = "gaitforge.gym_env:GymMuscleEnv"
ANY_SCENE = f"{NAMESPACE}/Scene-v0"


def scene_ids() -> dict[str, str]:
    """Gymnasium id -> catalogue base scene, for every base."""
    return {f"{NAMESPACE}/{name}-v0": name for name in base_names()}


def register_scenes() -> None:
    """Register :func:`scene_ids` and ``gaitforge/Scene-v0``; ids already registered (a
    second call) are left as they are."""
    from gymnasium.envs.registration import register, registry

    for env_id, scene in scene_ids().items():
        if env_id not in registry:
            register(id=env_id, entry_point=ENTRY_POINT, kwargs={"scene": scene})
    if ANY_SCENE not in registry:
        register(id=ANY_SCENE, entry_point=ENTRY_POINT)
