"""Size of an ``opensim.Model``, in the same terms as the MuJoCo backend's report."""

from __future__ import annotations

import opensim
from gaitforge.workers.bodies.topology import Topology
from gaitforge.workers.scenes.prune import PrunePlan
from gaitforge.workers.sim.opensim.build import OpenSimBuild


def full_plan(topology: Topology) -> PrunePlan:
    """The plan that removes nothing: every dof, muscle and contact sphere; no obstacles."""
    return PrunePlan(
        kept_dofs=list(topology.dof_defaults),
        locked_dofs={},
        kept_muscles=topology.muscles,
        removed_muscles={},
        contact_geoms=list(topology.contact_geoms),
        obstacles=0,
    )


def model_size(built: OpenSimBuild) -> dict[str, int]:
    """dofs, joints, bodies, muscles, tendons, wrap_objects, geoms (contact geometry),
    sites (muscle path points) and contact_pairs (each body sphere's Hunt-Crossley force
    acts between it and the floor and every obstacle)."""
    model = built.model
    muscles = model.getMuscles()
    bodies = model.getBodySet()
    return {
        "dofs": model.getCoordinateSet().getSize(),
        "joints": model.getJointSet().getSize(),
        "bodies": bodies.getSize(),
        "muscles": muscles.getSize(),
        "tendons": muscles.getSize(),
        "wrap_objects": sum(
            bodies.get(i).getWrapObjectSet().getSize() for i in range(bodies.getSize())
        ),
        "geoms": model.getContactGeometrySet().getSize(),
        "sites": sum(
            muscles.get(i).getGeometryPath().getPathPointSet().getSize()
            for i in range(muscles.getSize())
        ),
        "contact_pairs": _count_forces(model, "contact_") * (1 + len(built.obstacle_geometry)),
    }


def _count_forces(model: opensim.Model, prefix: str) -> int:
    forces = model.getForceSet()
    return sum(forces.get(i).getName().startswith(prefix) for i in range(forces.getSize()))
