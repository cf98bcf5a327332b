"""What a scene's env reads and drives, by name, without building a simulator: the
observation's entries, the action's (the kept muscles) and the world axes.

Computed from the body's topology and the scene's pruning plan and task. ``workers.env``
lays its observation out with :func:`observation_layout`, so the env and these names cannot
drift apart; a test over the whole catalogue checks them against built envs on every backend.

One case needs a measurement: ``keep.planar`` on MuJoCo keeps the muscles whose moment arms
act in the plane of the kept dofs (``workers.sim.mujoco.compile.planar_muscles_of`` measures them on
the unpruned model; no simulator is built). :func:`needs_planar_muscles` says when; the
OpenSim backend does not apply ``keep.planar``.
"""

from __future__ import annotations

from collections.abc import Sequence

from gaitforge.workers.bodies.topology import MJCF_BODIES, topology_for
from gaitforge.workers.scenes.prune import PrunePlan, plan_pruning
from gaitforge.workers.scenes.spec import Scene

XYZ = "xyz"


def observation_layout(
    scene: Scene, dofs: Sequence[str], feet: Sequence[str], muscles: Sequence[str]
) -> list[str]:
    """The observation's entry names, in order, for ``scene``'s task and the given kept dofs,
    feet and muscles (see ``workers.env`` for units): ``q:<dof>``, ``qd:<dof>``; locomotion:
    ``pelvis_height``, ``pelvis_up_{x,y,z}``, ``pelvis_vel_{x,y,z}``,
    ``pelvis_angvel_{x,y,z}``, ``grf:<foot>``; ``act:<muscle>``, ``prev_exc:<muscle>``;
    ``target_speed`` (locomotion) or ``reach_target``; with obstacles the observed spheres
    (``obstacle_names``); with the gait clock ``phase_sin``, ``phase_cos``,
    ``phase_mirror``."""
    locomotion = scene.task.kind == "locomotion"
    names = [f"q:{d}" for d in dofs] + [f"qd:{d}" for d in dofs]
    if locomotion:
        names += ["pelvis_height", *(f"pelvis_up_{a}" for a in XYZ)]
        names += [f"pelvis_vel_{a}" for a in XYZ] + [f"pelvis_angvel_{a}" for a in XYZ]
        names += [f"grf:{f}" for f in feet]
    names += [f"act:{m}" for m in muscles]
    names += [f"prev_exc:{m}" for m in muscles]
    names += ["target_speed"] if locomotion else ["reach_target"]
    if scene.obstacles is not None:
        names += obstacle_names(scene.obstacles.observe_ahead)
    if scene.task.clock is not None:
        names += ["phase_sin", "phase_cos", "phase_mirror"]
    return names


def obstacle_names(ahead: int) -> list[str]:
    """Forward distance, height and radius of each observed sphere: the nearest one ahead
    ``obstacle_{dx,height,radius}`` (the names of a scene that observes one), then the k-th
    ahead ``obstacle_<k>_*`` (k >= 2)."""
    prefixes = ["obstacle"] + [f"obstacle_{k}" for k in range(2, ahead + 1)]
    return [f"{p}_{field}" for p in prefixes for field in ("dx", "height", "radius")]


def action_layout(scene: Scene, dofs: Sequence[str], muscles: Sequence[str]) -> list[str]:
    """The action's entry names, in order, for ``scene`` and the given kept dofs and muscles:
    the muscles [n_muscles]; or, with ``action.kind: joint_targets``, ``target:<dof>``
    [n_dofs]."""
    return [f"target:{d}" for d in dofs] if scene.action.targets else list(muscles)


def needs_planar_muscles(scene: Scene, backend: str) -> bool:
    """Whether :func:`observation_names` and :func:`action_names` need the measured planar
    muscles for ``scene`` on ``backend`` (``keep.planar`` on MuJoCo)."""
    return scene.keep.planar and backend == "mujoco"


def kept_plan(scene: Scene, backend: str, planar_muscles: Sequence[str] | None = None) -> PrunePlan:
    """The pruning plan ``backend`` compiles ``scene`` with.

    Raises:
        ValueError: ``keep.planar`` on MuJoCo without ``planar_muscles``.
    """
    if needs_planar_muscles(scene, backend) and planar_muscles is None:
        raise ValueError(
            f"scene {scene.name!r}: keep.planar on mujoco needs the measured planar muscles "
            "(workers.sim.mujoco.compile.planar_muscles_of)"
        )
    planar = list(planar_muscles) if needs_planar_muscles(scene, backend) else None
    return plan_pruning(scene, topology_for(scene.body), planar)


def action_names(
    scene: Scene, backend: str = "mujoco", planar_muscles: Sequence[str] | None = None
) -> list[str]:
    """The action's entry names (see :func:`action_layout`), equal to the built env's
    ``act_names``."""
    plan = kept_plan(scene, backend, planar_muscles)
    return action_layout(scene, plan.kept_dofs, plan.kept_muscles)


def observation_names(
    scene: Scene, backend: str = "mujoco", planar_muscles: Sequence[str] | None = None
) -> list[str]:
    """The observation's entry names [n_obs] of ``scene`` on ``backend``, equal to the built
    env's ``obs_names`` (see :func:`observation_layout`)."""
    plan = kept_plan(scene, backend, planar_muscles)
    feet = sorted(topology_for(scene.body).feet)
    return observation_layout(scene, plan.kept_dofs, feet, plan.kept_muscles)


def world_axes(body: str) -> tuple[int, int]:
    """(up, forward) axes of the simulator's world for ``body``: MyoSuite's MJCF bodies are
    Z-up, neutral bodies Y-up; both face +X."""
    return (2, 0) if body in MJCF_BODIES else (1, 0)


def lateral_axis(body: str) -> int:
    """The world axis across the body (neither up nor forward)."""
    up, forward = world_axes(body)
    return 3 - up - forward
