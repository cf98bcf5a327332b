"""A scene compiled to a pruned MuJoCo model, with the report of what was removed.

The body's unpruned model is the source (a neutral body built by ``mujoco.build``, or a
MyoSuite MJCF); pruning welds the scene's locked joints, removes muscles, restricts contacts,
adds the scene's obstacles and strips visuals, then sets the fidelity profile's integrator
and timestep (and, where the scene asks, the muscles' active force curves fitted to
OpenSim's, or their passive curve fitted to Thelen's over its whole strain).
"""

from __future__ import annotations

from functools import lru_cache

import mujoco
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.topology import Topology, topology_for
from gaitforge.workers.scenes import PrunePlan, Scene, plan_pruning
from gaitforge.workers.sim.base import CompileReport
from gaitforge.workers.sim.mujoco.build import CONTACT_GROUP, FLOOR, build_spec
from gaitforge.workers.sim.mujoco.contacts import model_size, restrict_contacts
from gaitforge.workers.sim.mujoco.lock import lock_joints
from gaitforge.workers.sim.mujoco.mjcf_sources import MJCF_SOURCES
from gaitforge.workers.sim.mujoco.removal import remove_muscles, strip_unused
from gaitforge.workers.sim.muscle_curves import (
    MILLARD_ACTIVE_RANGE,
    MILLARD_FVMAX,
    MILLARD_VMAX_SCALE,
    fit_mujoco_passive_whole,
)

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}
OBSTACLE_PREFIX = "obstacle_"
PARKED = -100.0
"""Forward position (m) of obstacle geoms until the first reset places them."""


def source_spec(body: str) -> mujoco.MjSpec:
    """The body as an ``MjSpec`` with nothing removed."""
    if body in MJCF_SOURCES:
        return MJCF_SOURCES[body]()
    return build_spec(load_body(body))


@lru_cache(maxsize=8)
def _full_model_size(body: str) -> dict[str, int]:
    """Size of the unpruned model."""
    return model_size(source_spec(body).compile())


def _add_obstacles(spec: mujoco.MjSpec, count: int) -> list[str]:
    names = [f"{OBSTACLE_PREFIX}{i}" for i in range(count)]
    for name in names:
        spec.worldbody.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[0.1, 0, 0],
            pos=[PARKED, 0, 0],
            group=CONTACT_GROUP,
            rgba=[0.6, 0.4, 0.3, 1.0],
        )
    return names


def _fit_muscle_curves_to_millard(model: mujoco.MjModel) -> None:
    """Every muscle's active force (``gainprm``: ``lmin``, ``lmax``, ``vmax``, ``fvmax`` at
    4, 5, 6, 8) fitted to Millard 2012's curves (``muscle_curves.MILLARD_ACTIVE_RANGE``);
    the passive force (``biasprm``) is left as it is."""
    muscles = model.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE
    model.actuator_gainprm[muscles, 4:6] = MILLARD_ACTIVE_RANGE
    model.actuator_gainprm[muscles, 6] *= MILLARD_VMAX_SCALE
    model.actuator_gainprm[muscles, 8] = MILLARD_FVMAX


def _fit_passive_to_thelen_whole(model: mujoco.MjModel, scene: Scene) -> None:
    """Every kept muscle's passive force (``biasprm``: ``lmax``, ``fpmax`` at 5, 7) fitted to
    Thelen's curve over its whole strain (``muscle_curves.fit_mujoco_passive_whole``), of
    MuJoCo's normalised length (``thelen``) or of the pennated fibre's own length, projected
    on the tendon as OpenSim's rigid-tendon muscle does (``thelen-fibre``); the active force
    (``gainprm``) is left as it is.

    Raises:
        ValueError: the body is a MuJoCo MJCF (no Thelen parameters to fit to).
    """
    if scene.body in MJCF_SOURCES:
        raise ValueError(
            f"scene {scene.name!r}: mujoco.muscle_passive {scene.mujoco.muscle_passive!r} needs "
            f"a body with Thelen passive parameters (a body file such as gait2d); "
            f"{scene.body!r} is a MuJoCo MJCF"
        )
    for muscle in load_body(scene.body).muscles:
        actuator = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, muscle.name)
        if actuator >= 0:  # kept by the scene
            pennation = (
                muscle.pennation_angle if scene.mujoco.muscle_passive == "thelen-fibre" else 0.0
            )
            lmax, fpmax = fit_mujoco_passive_whole(
                muscle.passive_fibre_strain, muscle.passive_shape, pennation
            )
            model.actuator_biasprm[actuator, 5] = lmax
            model.actuator_biasprm[actuator, 7] = fpmax


def compile_scene(scene: Scene) -> tuple[mujoco.MjModel, CompileReport, Topology]:
    """Compile ``scene`` to a pruned model, with the report of what was removed."""
    topology = topology_for(scene.body)
    size_full = _full_model_size(scene.body)
    plan: PrunePlan = plan_pruning(scene, topology)
    spec = source_spec(scene.body)
    dropped = lock_joints(spec, plan.locked_dofs)
    remove_muscles(spec, list(plan.removed_muscles))
    obstacles = _add_obstacles(spec, plan.obstacles)
    world = [g.name for g in spec.geoms if g.name in {FLOOR, *obstacles}]
    restrict_contacts(spec, plan.contact_geoms if world else [], world)
    if not scene.keep.visuals:
        strip_unused(spec)
    for geom in spec.geoms:
        if geom.name == FLOOR:
            geom.friction = [scene.terrain.friction, 0.005, 0.0001]
    profile = scene.profile("mujoco")
    spec.option.integrator = INTEGRATORS[profile.integrator]
    spec.option.timestep = profile.timestep
    model = spec.compile()
    muscles = model.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE
    options = scene.mujoco
    if options.muscle_min_activation > 0:
        model.actuator_ctrllimited[muscles] = 1
        model.actuator_ctrlrange[muscles] = (options.muscle_min_activation, 1.0)
    if options.contact_solimp is not None:
        model.geom_solimp[:] = options.contact_solimp
        model.pair_solimp[:] = options.contact_solimp
    if options.muscle_curves == "millard":
        _fit_muscle_curves_to_millard(model)
    if options.muscle_passive != "gait":
        _fit_passive_to_thelen_whole(model, scene)
    report = CompileReport(
        scene=scene.name,
        backend="mujoco",
        body=scene.body,
        profile=profile,
        plan=plan,
        size_full=size_full,
        size=model_size(model),
        mass=float(sum(model.body_mass)),
        dropped_joints=dropped,
    )
    return model, report, topology
