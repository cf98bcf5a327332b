"""Topology of MyoSuite's MJCF bodies, read from their compiled MuJoCo models.

The scenes layer reads it as committed data (``workers/bodies/data/topology/<body>.yaml``,
see ``workers.bodies.topology``) and never compiles a model for it. This script writes that
data, once per myo-sim version, and ``tests/workers/bodies/test_mjcf_topology.py`` checks it:

    python bench/data/mjcf_topology.py --write
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import mujoco
import yaml
from gaitforge.workers.bodies.topology import MJCF_BODIES, Topology, topology_file
from gaitforge.workers.sim.mujoco.mjcf_sources import MJCF_SOURCES
from gaitforge.workers.sim.mujoco.moment_arms import muscle_spans

logger = logging.getLogger(__name__)

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
    and which of them are feet, from the installed myo-sim model."""
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


def topology_yaml(body: str) -> str:
    """The committed form of ``body``'s topology, as written by ``--write``."""
    header = (
        f"# Topology of MyoSuite's {body} (myo-sim), written by\n"
        "# python bench/data/mjcf_topology.py --write; do not edit by hand.\n"
    )
    return header + yaml.safe_dump(mjcf_topology(body).to_data(), sort_keys=False)


def write_all() -> list[Path]:
    """Write every MJCF body's topology file; returns the files."""
    paths = []
    for body in MJCF_BODIES:
        path = topology_file(body)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(topology_yaml(body))
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write the topology files")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if not args.write:
        parser.print_help()
        return 2
    for path in write_all():
        logger.info("wrote %s", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
