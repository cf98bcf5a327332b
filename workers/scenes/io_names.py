"""What a scene's env reads and drives, by name, without building a simulator: the
observation's entries, the action's (the kept muscles) and the world axes.

The observation's order is written once, in :data:`OBSERVATION`: one entry per part (its
key, when a scene observes it, its names and so its size, and what it holds, with units).
``workers.env`` binds a reader to each key and assembles the vector in this table's order;
its names come from :func:`observation_parts`, as those asked here without an env do. A test
over the whole catalogue checks the names asked of the scene against built envs on every
backend (the kept dofs, feet and muscles of the pruning plan against those the simulator
built), and the env counts every entry's values against its names at each reset.

Computed from the body's topology and the scene's pruning plan and task.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from gaitforge.workers.bodies.topology import MJCF_BODIES, topology_for
from gaitforge.workers.scenes.prune import plan_pruning
from gaitforge.workers.scenes.spec import Scene

XYZ = "xyz"


@dataclass(frozen=True)
class Observed:
    """What the observation's names depend on: the scene, its kept dofs, its feet (sorted)
    and its kept muscles, each in the simulator's order."""

    scene: Scene
    dofs: Sequence[str]
    feet: Sequence[str]
    muscles: Sequence[str]


@dataclass(frozen=True)
class ObservationEntry:
    """One part of the observation.

    Attributes:
        key: what the env reads for it (``workers.env`` binds one reader to each key).
        when: whether a scene observes it.
        names: its entries' names, in order: their count is the part's size.
        holds: what it holds, with its size and units (for the reader).
    """

    key: str
    when: Callable[[Scene], bool]
    names: Callable[[Observed], list[str]]
    holds: str


def _always(scene: Scene) -> bool:
    return True


def _locomotion(scene: Scene) -> bool:
    return scene.task.kind == "locomotion"


def _reaching(scene: Scene) -> bool:
    return scene.task.kind != "locomotion"


def _with_obstacles(scene: Scene) -> bool:
    return scene.obstacles is not None


def _with_clock(scene: Scene) -> bool:
    return scene.task.clock is not None


def _sphere_names(scene: Scene) -> list[str]:
    return obstacle_names(scene.obstacles.observe_ahead) if scene.obstacles is not None else []


def _per_axis(prefix: str) -> Callable[[Observed], list[str]]:
    return lambda _: [f"{prefix}_{a}" for a in XYZ]


OBSERVATION: tuple[ObservationEntry, ...] = (
    ObservationEntry(
        "dof_pos", _always, lambda o: [f"q:{d}" for d in o.dofs], "dof angles [n_dofs], rad or m"
    ),
    ObservationEntry(
        "dof_vel",
        _always,
        lambda o: [f"qd:{d}" for d in o.dofs],
        "dof speeds [n_dofs], rad/s or m/s",
    ),
    ObservationEntry(
        "pelvis_height", _locomotion, lambda _: ["pelvis_height"], "pelvis height [1], m"
    ),
    ObservationEntry(
        "pelvis_up",
        _locomotion,
        _per_axis("pelvis_up"),
        "the pelvis's up axis in the world [3], unit",
    ),
    ObservationEntry(
        "pelvis_vel", _locomotion, _per_axis("pelvis_vel"), "pelvis linear velocity [3], m/s"
    ),
    ObservationEntry(
        "pelvis_angvel",
        _locomotion,
        _per_axis("pelvis_angvel"),
        "pelvis angular velocity [3], rad/s",
    ),
    ObservationEntry(
        "foot_forces",
        _locomotion,
        lambda o: [f"grf:{f}" for f in o.feet],
        "normal ground force per foot [n_feet], body weights",
    ),
    ObservationEntry(
        "activations",
        _always,
        lambda o: [f"act:{m}" for m in o.muscles],
        "muscle activations [n_muscles], in [0, 1]",
    ),
    ObservationEntry(
        "prev_excitation",
        _always,
        lambda o: [f"prev_exc:{m}" for m in o.muscles],
        "the previous step's excitations [n_muscles], in [0, 1]",
    ),
    ObservationEntry(
        "target_speed",
        _locomotion,
        lambda _: ["target_speed"],
        "the target speed [1], m/s (0 without one)",
    ),
    ObservationEntry(
        "reach_target", _reaching, lambda _: ["reach_target"], "the reach target [1], rad"
    ),
    ObservationEntry(
        "obstacles",
        _with_obstacles,
        lambda o: _sphere_names(o.scene),
        "the observed spheres ahead [3 * obstacles.observe_ahead]: forward distance from the "
        "pelvis, centre height, radius, m",
    ),
    ObservationEntry(
        "gait_phase",
        _with_clock,
        lambda _: ["phase_sin", "phase_cos", "phase_mirror"],
        "the gait clock's phase [3]: its sine and cosine, +1 in a mirrored episode else -1",
    ),
)
"""The observation's parts, in order: the only place the order is written."""


def observation_parts(
    scene: Scene, dofs: Sequence[str], feet: Sequence[str], muscles: Sequence[str]
) -> list[tuple[str, list[str]]]:
    """(key, entry names) of each part of :data:`OBSERVATION` that ``scene`` observes, in
    order, for the given kept dofs, feet and muscles."""
    observed = Observed(scene, tuple(dofs), tuple(feet), tuple(muscles))
    return [(e.key, e.names(observed)) for e in OBSERVATION if e.when(scene)]


def observation_layout(
    scene: Scene, dofs: Sequence[str], feet: Sequence[str], muscles: Sequence[str]
) -> list[str]:
    """The observation's entry names [n_obs], in order (:func:`observation_parts` one after
    the other): ``q:<dof>``, ``qd:<dof>``, ``pelvis_up_x``, ``grf:<foot>``, ``act:<muscle>``,
    ... (see :data:`OBSERVATION`)."""
    return [name for _, names in observation_parts(scene, dofs, feet, muscles) for name in names]


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


def action_names(scene: Scene, backend: str = "mujoco") -> list[str]:
    """The action's entry names (see :func:`action_layout`), equal to the built env's
    ``act_names`` on ``backend`` (either: both compile the same plan)."""
    plan = plan_pruning(scene, topology_for(scene.body))
    return action_layout(scene, plan.kept_dofs, plan.kept_muscles)


def observation_names(scene: Scene, backend: str = "mujoco") -> list[str]:
    """The observation's entry names [n_obs] of ``scene`` on ``backend``, equal to the built
    env's ``obs_names`` (see :func:`observation_layout`)."""
    plan = plan_pruning(scene, topology_for(scene.body))
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
