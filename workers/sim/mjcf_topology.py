"""Topology of MyoSuite's MJCF bodies, read from their compiled MuJoCo models."""

from __future__ import annotations

import mujoco
from gaitforge.workers.scenes.topology import Topology
from gaitforge.workers.sim.mjcf_moment_arms import muscle_spans
from gaitforge.workers.sim.mjcf_sources import MJCF_SOURCES

FOOT_BODIES = {"foot_right": ("calcn_r", "toes_r"), "foot_left": ("calcn_l", "toes_l")}
"""Bodies whose collision geoms count as feet (MyoLeg naming)."""


def dependent_joints(model: mujoco.MjModel) -> dict[str, str]:
    """Joints driven by another through a joint equality: dependent -> driving joint."""
    out: dict[str, str] = {}
    for i in range(model.neq):
        if model.eq_type[i] == mujoco.mjtEq.mjEQ_JOINT and model.eq_obj2id[i] >= 0:
            out[model.joint(model.eq_obj1id[i]).name] = model.joint(model.eq_obj2id[i]).name
    return out


def mjcf_topology(body: str) -> Topology:
    """Dofs (free root and equality-driven joints excluded), muscle spans, colliding geoms
    and which of them are feet."""
    model = MJCF_SOURCES[body]().compile()
    dependent = dependent_joints(model)
    root_dofs: list[str] = []
    defaults: dict[str, float] = {}
    for j in range(model.njnt):
        name = model.joint(j).name
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            root_dofs.append(name)
        elif name not in dependent:
            defaults[name] = float(model.qpos0[model.jnt_qposadr[j]])
    spans = {
        muscle: sorted({dependent.get(j, j) for j in joints})
        for muscle, joints in muscle_spans(model).items()
    }
    feet: dict[str, list[str]] = {}
    for foot, body_names in FOOT_BODIES.items():
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in body_names]
        geoms = [
            model.geom(g).name
            for g in range(model.ngeom)
            if model.geom_bodyid[g] in ids and (model.geom_contype[g] or model.geom_conaffinity[g])
        ]
        if geoms:
            feet[foot] = geoms
    colliding = [
        model.geom(g).name
        for g in range(model.ngeom)
        if model.geom_bodyid[g] > 0 and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]
    return Topology(
        dof_defaults=defaults,
        root_dofs=root_dofs,
        root_defaults={},
        muscle_spans=spans,
        contact_geoms=colliding,
        feet=feet,
    )
