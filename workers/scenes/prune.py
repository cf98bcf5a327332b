"""Pruning: decide what a scene keeps of its body, and say why each part was dropped."""

from __future__ import annotations

from dataclasses import dataclass, field

from gaitforge.workers.bodies.topology import Topology
from gaitforge.workers.scenes.clock import check_clock
from gaitforge.workers.scenes.spec import Scene


@dataclass(frozen=True)
class PrunePlan:
    """The scene's decisions, backend-neutral; each backend applies them to its model.

    Attributes:
        kept_dofs: dofs that move.
        locked_dofs: dof -> value it is welded at (rad or m).
        kept_muscles: muscles in the compiled model, in the body's order.
        removed_muscles: muscle -> reason.
        contact_geoms: body geoms that may touch the ground (and obstacles).
        obstacles: number of obstacle spheres in the world.
    """

    kept_dofs: list[str]
    locked_dofs: dict[str, float]
    kept_muscles: list[str]
    removed_muscles: dict[str, str]
    contact_geoms: list[str]
    obstacles: int
    notes: list[str] = field(default_factory=list)


def check_names(scene: Scene, topology: Topology) -> None:
    """Raise ``ValueError`` naming the field if the scene names a dof or muscle the body lacks."""
    dofs = set(topology.dof_defaults)
    muscles = set(topology.muscles)
    if scene.keep.joints != "all":
        for i, name in enumerate(scene.keep.joints):
            if name not in dofs:
                raise ValueError(
                    f"keep.joints.{i}: unknown joint {name!r}; body {scene.body!r} has "
                    f"{sorted(dofs)}"
                )
    for name in scene.keep.lock_at:
        if name not in dofs:
            raise ValueError(f"keep.lock_at.{name}: unknown joint; allowed: {sorted(dofs)}")
    if scene.keep.muscles != "all":
        for i, name in enumerate(scene.keep.muscles):
            if name not in muscles:
                raise ValueError(
                    f"keep.muscles.{i}: unknown muscle {name!r}; body {scene.body!r} has "
                    f"{sorted(muscles)}"
                )
    if scene.task.reach_dof is not None and scene.task.reach_dof not in dofs:
        raise ValueError(f"task.reach_dof: unknown joint {scene.task.reach_dof!r}")
    check_clock(scene.task.clock, scene.body, scene.keep.joints, topology)


def plan_pruning(scene: Scene, topology: Topology) -> PrunePlan:
    """What ``scene`` keeps of the body described by ``topology``."""
    check_names(scene, topology)
    wanted = set(topology.dof_defaults if scene.keep.joints == "all" else scene.keep.joints)
    if scene.task.reach_dof:
        wanted.add(scene.task.reach_dof)
    kept_dofs = [d for d in topology.dof_defaults if d in wanted]
    locked = {
        d: scene.keep.lock_at.get(d, default)
        for d, default in topology.dof_defaults.items()
        if d not in wanted
    }
    asked = set(topology.muscles if scene.keep.muscles == "all" else scene.keep.muscles)
    kept_muscles: list[str] = []
    removed: dict[str, str] = {}
    for muscle, spans in topology.muscle_spans.items():
        if muscle not in asked:
            removed[muscle] = "not in keep.muscles"
        elif not any(d in wanted or d in topology.root_dofs for d in spans):
            removed[muscle] = "spans only locked joints"
        else:
            kept_muscles.append(muscle)
    feet = [g for geoms in topology.feet.values() for g in geoms]
    if scene.task.kind != "locomotion":
        contact: list[str] = []
    elif scene.keep.contacts == "all":
        contact = topology.contact_geoms
    else:
        contact = feet
    return PrunePlan(
        kept_dofs=kept_dofs,
        locked_dofs=locked,
        kept_muscles=kept_muscles,
        removed_muscles=removed,
        contact_geoms=list(contact),
        obstacles=scene.obstacles.count if scene.obstacles else 0,
    )
