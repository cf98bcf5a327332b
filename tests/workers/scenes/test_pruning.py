"""Pruning removes exactly what the scene says, and nothing else."""

from __future__ import annotations

import mujoco
import pytest
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

GAIT2D_MUSCLES = 18


def _variant(name: str, **keep) -> Scene:
    scene = load_scene(name)
    return scene.model_copy(update={"keep": scene.keep.model_copy(update=keep)})


def test_walk_2d_welds_the_lumbar_joint_and_keeps_every_muscle() -> None:
    report = MujocoSimulator(load_scene("walk-2d")).report
    assert list(report.plan.locked_dofs) == ["lumbar_extension"]
    assert report.dropped_joints == ["lumbar_extension"]
    assert report.size["muscles"] == GAIT2D_MUSCLES
    assert report.size["dofs"] == report.size_full["dofs"] - 1 == 9
    assert report.plan.removed_muscles == {}


def test_only_the_feet_touch_the_floor_and_obstacles_exist_only_where_asked() -> None:
    walk = MujocoSimulator(load_scene("walk-2d")).report
    assert walk.size["contact_pairs"] == 4  # four foot spheres x floor
    assert walk.size_full["contact_pairs"] > walk.size["contact_pairs"]
    obstacles = MujocoSimulator(load_scene("obstacles-2d")).report
    assert obstacles.plan.obstacles == 10
    assert obstacles.size["contact_pairs"] == 4 * (1 + 10)
    assert obstacles.size["geoms"] == walk.size["geoms"] + 10


def test_locking_the_knees_removes_exactly_the_knee_only_muscles() -> None:
    kept = ["hip_flexion_r", "ankle_angle_r", "hip_flexion_l", "ankle_angle_l"]
    report = MujocoSimulator(_variant("walk-2d", joints=kept)).report
    spans = topology_for("gait2d").muscle_spans
    knee_only = {m for m, dofs in spans.items() if set(dofs) <= {"knee_angle_r", "knee_angle_l"}}
    assert knee_only == {"vasti_r", "vasti_l", "bifemsh_r", "bifemsh_l"}
    assert set(report.plan.removed_muscles) == knee_only
    assert report.size["muscles"] == GAIT2D_MUSCLES - 4
    assert {"knee_angle_r", "knee_angle_l", "lumbar_extension"} == set(report.plan.locked_dofs)
    assert report.size["dofs"] == 9 - 2


def test_keep_muscles_keeps_exactly_those() -> None:
    chosen = ["soleus_r", "tib_ant_r", "soleus_l", "tib_ant_l"]
    sim = MujocoSimulator(_variant("stand-2d", muscles=chosen))
    assert sim.muscle_names == chosen
    assert sim.report.size["tendons"] == 4


def test_lock_at_overrides_the_default() -> None:
    scene = _variant("walk-2d", lock_at={"lumbar_extension": 0.2})
    assert MujocoSimulator(scene).report.plan.locked_dofs == {"lumbar_extension": 0.2}


def test_walk_3d_drops_subtalar_and_toes_and_the_muscles_that_only_span_them() -> None:
    report = MujocoSimulator(load_scene("walk-3d")).report
    locked = set(report.plan.locked_dofs)
    assert locked == {f"{j}_{s}" for j in ("subtalar_angle", "mtp_angle") for s in "rl"}
    spans = topology_for("myoleg").muscle_spans
    only_locked = {m for m, dofs in spans.items() if dofs and set(dofs) <= locked}
    assert set(report.plan.removed_muscles) == only_locked
    assert report.size["muscles"] == 80 - len(only_locked)
    assert report.size["dofs"] < report.size_full["dofs"]
    assert report.size["contact_pairs"] < report.size_full["contact_pairs"]


def test_training_scenes_drop_drawing_only_parts_and_visuals_keeps_them() -> None:
    """Bone meshes, visual capsules and markers cost kinematics time and memory, not physics."""
    lean = MujocoSimulator(load_scene("walk-3d"))
    drawn = MujocoSimulator(_variant("walk-3d", visuals=True))
    mesh = int(mujoco.mjtGeom.mjGEOM_MESH)
    n_lean, n_drawn = ((sim.model.geom_type == mesh).sum() for sim in (lean, drawn))
    assert n_drawn > 10
    assert n_lean <= 6, "only meshes that give their body its mass (talus, toes, patella)"
    assert lean.report.size["sites"] < drawn.report.size["sites"]
    assert lean.report.size["contact_pairs"] == drawn.report.size["contact_pairs"]
    assert lean.report.size["muscles"] == drawn.report.size["muscles"] == 80
    assert lean.report.mass == pytest.approx(drawn.report.mass)


def test_contacts_all_lets_every_body_geom_touch_the_ground() -> None:
    feet = MujocoSimulator(load_scene("walk-3d")).report
    everything = MujocoSimulator(_variant("walk-3d", contacts="all")).report
    assert feet.size["contact_pairs"] == len(feet.plan.contact_geoms) == 10
    # the legs' 20 and the torso's 8 (trunk and arms)
    assert everything.size["contact_pairs"] == len(everything.plan.contact_geoms) == 28
