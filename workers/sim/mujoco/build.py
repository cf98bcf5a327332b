"""Build a MuJoCo model (``mujoco.MjSpec``) from a neutral :class:`~workers.bodies.Body`.

Naming in the compiled model: bodies are segments, joints are dofs, tendons and actuators
are muscles, wrap geoms are wrap objects (side sites ``<wrap>_side``), path sites are
``<muscle>_p<i>``, contact geoms are contact spheres, markers are sites. The world is
Y-up with gravity along -Y, as in the neutral format; the floor geom is ``floor``.

Muscles: MuJoCo's muscle has no fibre length parameter of its own; it derives the optimal
length ``L0`` and tendon length ``LT`` from ``lengthrange`` and ``range`` as
``L0 = (lr1 - lr0) / (r1 - r0)``, ``LT = lr0 - r0 * L0``. We set ``lengthrange`` so that
``L0`` is the optimal fibre length projected on the tendon (``l_opt cos(pennation)``) and
``LT`` the tendon slack length: a rigid-tendon Hill muscle with the same operating point.
MuJoCo's muscle has no pennation, so its peak force is the max isometric force projected on
the tendon, ``F_max cos(pennation)``, as a pennated Hill muscle delivers at optimal length.
Its passive force follows Thelen 2003's (see ``muscle_curves``); MuJoCo's default passive
curve is two to three times stiffer than the reference's.

Bodies imported from OpenSim (``gaitforge bodies import``) use features MuJoCo lacks or has
in another form:

* a joint's ``orientation_in_parent`` (X-Y-Z body-fixed Euler angles) is the child body's
  ``quat``; products of inertia make the body's ``fullinertia``;
* MuJoCo refuses principal moments of inertia that break the triangle inequality
  (``A + B >= C``), which OpenSim accepts (leg6dof9musc's toes: 1e-6, 1e-6, 9e-4 kg m^2):
  the compiler's ``balanceinertia`` replaces such a segment's moments by their mean;
* a coupled dof is an unlimited joint held to its driver by a quartic polynomial (a joint
  equality ``couple_<dof>``): see :mod:`workers.sim.mujoco.couplings`, which also reports
  each polynomial's fit error and places coupled joints exactly;
* MuJoCo has neither conditional nor moving sites: a point with a ``stand_in`` (the
  importer fits one to keep the muscle's moment arms) becomes that fixed site, none, the
  wrap object it names (a wrap cylinder fitted in place of a conditional point), or a site
  on a carrier whose slides follow the stand-in's quartics (``follow``, a moving point;
  :func:`workers.sim.mujoco.couplings.add_carrier`).
  Without one, a conditional path point is kept (as an ordinary site) iff the default of
  its coordinate lies in its active range, and dropped otherwise, unless dropping it would
  leave a wrap object or the path's end without a site (then it is kept, with a warning);
  a moving path point is a fixed site at ``location`` (its place at its coordinate's
  default);
* MuJoCo's tendons wrap only spheres and cylinders: an ellipsoid wrap object is a sphere of
  its ``radius``. A wrap object's ``orientation`` (X-Y-Z Euler angles), where given, turns
  its geom; without it a cylinder's +Z is turned onto ``axis``.
"""

from __future__ import annotations

import logging
import math

import mujoco
import numpy as np
from gaitforge.workers.bodies.schema import (
    GROUND,
    Body,
    Muscle,
    PathElement,
    PathPoint,
    Vec3,
    WrapObject,
    WrapRef,
)
from gaitforge.workers.sim.mujoco.couplings import add_carrier, add_couplings
from gaitforge.workers.sim.mujoco.warning_log import route_warnings
from gaitforge.workers.sim.muscle_curves import fit_mujoco_fpmax

logger = logging.getLogger(__name__)
route_warnings()  # MuJoCo's warnings to logging, not to MUJOCO_LOG.TXT in the cwd

FLOOR = "floor"
MUSCLE_RANGE = (0.75, 1.05)
"""Normalised fibre lengths that map onto ``lengthrange`` (any consistent pair works)."""
ACTIVE_RANGE = (0.4441, 1.8)
"""MuJoCo ``lmin``, ``lmax``: normalised fibre lengths where active force vanishes, those of
Millard 2012's default active force-length curve (the OpenSim backend's muscle)."""
FIBRE_DAMPING = 0.1
"""Fibre damping as a fraction of max isometric force per max contraction velocity (Millard
2012's default, the OpenSim backend's muscle): a tendon damping of
``0.1 F_max / (v_max l_opt)`` N s/m. Without it a relaxed foot rattles on its passive springs."""
CONTACT_GROUP = 1
VISUAL_GROUP = 2
WRAP_GROUP = 3


def quat_from_z(axis: tuple[float, float, float]) -> np.ndarray:
    """Quaternion (w, x, y, z) rotating +Z onto ``axis``."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, a)
    return quat


def quat_from_euler_xyz(angles: Vec3) -> np.ndarray:
    """Quaternion (w, x, y, z) of body-fixed X-Y-Z Euler angles (rad), OpenSim's frame
    ``orientation``: ``R = Rx(a) @ Ry(b) @ Rz(c)``."""
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    for axis, angle in zip(np.eye(3), angles, strict=True):
        turn = np.zeros(4)
        mujoco.mju_axisAngle2Quat(turn, axis, float(angle))
        mujoco.mju_mulQuat(quat, quat.copy(), turn)
    return quat


def _add_floor(spec: mujoco.MjSpec, friction: float) -> None:
    spec.worldbody.add_geom(
        name=FLOOR,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[50.0, 50.0, 0.1],
        quat=quat_from_z((0.0, 1.0, 0.0)),
        friction=[friction, 0.005, 0.0001],
        rgba=[0.75, 0.8, 0.85, 1.0],
        group=CONTACT_GROUP,
    )


def _add_segments(spec: mujoco.MjSpec, body: Body) -> dict[str, mujoco.MjsBody]:
    bodies: dict[str, mujoco.MjsBody] = {GROUND: spec.worldbody}
    for joint in body.ordered_joints():
        seg = body.segment(joint.child)
        mj_body = bodies[joint.parent].add_body(
            name=seg.name,
            pos=list(joint.location_in_parent),
            quat=quat_from_euler_xyz(joint.orientation_in_parent).tolist(),
            mass=seg.mass,
            ipos=list(seg.com),
            explicitinertial=True,
        )
        if any(seg.inertia_products):  # MuJoCo's order: ixx iyy izz ixy ixz iyz
            mj_body.fullinertia = [*seg.inertia, *seg.inertia_products]
        else:
            mj_body.inertia = list(seg.inertia)
        # The root's dofs place the body in the world: never limited (OpenSim clamps no
        # coordinate either). A range there is a wall: gait2d's pelvis_tx range of +-5 m
        # stopped every walker 5 m from the origin. A coupled dof follows its driver
        # (``couplings``): a limit of its own would fight the coupling.
        in_world = joint.parent == GROUND
        for dof in joint.dofs:
            kind = (
                mujoco.mjtJoint.mjJNT_HINGE if dof.type == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE
            )
            mj_body.add_joint(
                name=dof.name,
                type=kind,
                axis=list(dof.axis),
                range=list(dof.limit.range if dof.limit else dof.range),
                limited=mujoco.mjtLimited.mjLIMITED_TRUE
                if (dof.limited or dof.limit is not None) and not in_world and dof.coupled is None
                else 0,
            )
        if seg.length_hint > 0:
            mj_body.add_geom(
                name=f"{seg.name}_visual",
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                fromto=[0, 0, 0, 0, -seg.length_hint, 0],
                size=[0.03, 0, 0],
                contype=0,
                conaffinity=0,
                group=VISUAL_GROUP,
                rgba=[0.9, 0.87, 0.8, 1.0],
            )
        bodies[seg.name] = mj_body
    return bodies


def _add_wrap(mj_body: mujoco.MjsBody, wrap: WrapObject) -> None:
    """A cylinder or sphere geom (an ellipsoid becomes the sphere of its ``radius``)."""
    is_cyl = wrap.type == "cylinder"
    quat = (
        quat_from_euler_xyz(wrap.orientation)
        if wrap.orientation is not None
        else quat_from_z(wrap.axis)
    )
    if wrap.type == "ellipsoid":
        logger.info(
            "wrap object %r: ellipsoid of semi-axes %s wrapped as a sphere of radius %g m",
            wrap.name,
            wrap.radii,
            wrap.radius,
        )
    mj_body.add_geom(
        name=wrap.name,
        type=mujoco.mjtGeom.mjGEOM_CYLINDER if is_cyl else mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[wrap.radius, wrap.length / 2 if is_cyl else 0, 0],
        pos=list(wrap.location),
        quat=quat.tolist(),
        contype=0,
        conaffinity=0,
        group=WRAP_GROUP,
        rgba=[0.5, 0.5, 0.9, 0.4],
    )
    if wrap.side is not None:
        mj_body.add_site(name=f"{wrap.name}_side", pos=list(wrap.side), group=WRAP_GROUP)


def _point_kept(point: PathPoint, body: Body) -> bool:
    """A conditional point is kept as its stand-in says, or else iff its coordinate's default
    lies in its active range."""
    if point.stand_in is not None:
        return point.stand_in.keep
    if point.active_when is None:
        return True
    lo, hi = point.active_when.range
    return lo <= body.dof(point.active_when.coordinate).default <= hi


def _mujoco_path(muscle: Muscle, body: Body) -> list[tuple[int, PathElement]]:
    """The muscle's path elements MuJoCo keeps, with their indices in ``muscle.path``.

    Inactive conditional points (:func:`_point_kept`) are dropped, except one whose absence
    would leave a wrap object without a site on each side or the path without its ends."""
    path = muscle.path
    kept: list[tuple[int, PathElement]] = []
    for i, element in enumerate(path):
        if isinstance(element, PathPoint) and element.stand_in and element.stand_in.wrap:
            kept.append((i, WrapRef(wrap=element.stand_in.wrap)))
            continue
        if isinstance(element, PathPoint) and not _point_kept(element, body):
            needed = (
                i in (0, len(path) - 1)
                or isinstance(path[i - 1], WrapRef)
                or isinstance(path[i + 1], WrapRef)
            )
            if not needed:
                logger.info("muscle %r: conditional point %d inactive at default", muscle.name, i)
                continue
            logger.warning(
                "muscle %r: conditional point %d is inactive at its coordinate's default but "
                "kept: the path needs a site there",
                muscle.name,
                i,
            )
        kept.append((i, element))
    return kept


def _add_muscles(spec: mujoco.MjSpec, body: Body, bodies: dict[str, mujoco.MjsBody]) -> None:
    wraps = {w.name: w for w in body.wrap_objects}
    for wrap in body.wrap_objects:
        _add_wrap(bodies[wrap.segment], wrap)
    for muscle in body.muscles:
        tendon = spec.add_tendon(
            name=muscle.name,
            width=0.006,
            rgba=[0.8, 0.2, 0.2, 1],
            damping=FIBRE_DAMPING
            * muscle.max_isometric_force
            / (muscle.max_contraction_velocity * muscle.optimal_fiber_length),
        )
        for i, element in _mujoco_path(muscle, body):
            if isinstance(element, PathPoint):
                site = f"{muscle.name}_p{i}"
                stand_in = element.stand_in
                if stand_in and stand_in.follow and element.moves_with:
                    driver = element.moves_with.coordinate
                    host = bodies[element.segment]
                    carrier = add_carrier(spec, host, site, driver, stand_in.follow)
                    carrier.add_site(name=site, pos=[0.0, 0.0, 0.0])
                else:
                    segment = (stand_in and stand_in.segment) or element.segment
                    location = (stand_in and stand_in.location) or element.location
                    bodies[segment].add_site(name=site, pos=list(location))
                tendon.wrap_site(site)
            else:
                side = wraps[element.wrap].side is not None and element.use_side
                tendon.wrap_geom(element.wrap, f"{element.wrap}_side" if side else "")
        fibre = muscle.optimal_fiber_length * math.cos(muscle.pennation_angle)
        lo, hi = MUSCLE_RANGE
        actuator = spec.add_actuator(
            name=muscle.name,
            target=muscle.name,
            trntype=mujoco.mjtTrn.mjTRN_TENDON,
            lengthrange=[
                muscle.tendon_slack_length + lo * fibre,
                muscle.tendon_slack_length + hi * fibre,
            ],
        )
        actuator.set_to_muscle(
            timeconst=[muscle.activation_time, muscle.deactivation_time],
            tausmooth=0.0,
            range=list(MUSCLE_RANGE),
            force=muscle.max_isometric_force * math.cos(muscle.pennation_angle),
            vmax=muscle.max_contraction_velocity,
            lmin=ACTIVE_RANGE[0],
            lmax=ACTIVE_RANGE[1],
            fpmax=fit_mujoco_fpmax(
                muscle.passive_fibre_strain, muscle.passive_shape, ACTIVE_RANGE[1]
            ),
        )


def _add_contacts(body: Body, bodies: dict[str, mujoco.MjsBody]) -> None:
    for sphere in body.contact_spheres:
        bodies[sphere.segment].add_geom(
            name=sphere.name,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[sphere.radius, 0, 0],
            pos=list(sphere.location),
            friction=[body.contact.static_friction, 0.005, 0.0001],
            group=CONTACT_GROUP,
            rgba=[0.3, 0.6, 0.3, 1.0],
        )


def build_spec(body: Body) -> mujoco.MjSpec:
    """The whole body as an ``MjSpec``: every dof a joint, every muscle an actuator.

    Pruning (locking joints, removing muscles and contacts) happens afterwards on the spec.
    """
    spec = mujoco.MjSpec()
    spec.modelname = body.name
    spec.option.gravity = [0.0, -9.81, 0.0]
    spec.compiler.autolimits = True
    spec.compiler.degree = False
    spec.compiler.balanceinertia = True  # see the module docstring (imported bodies)
    _add_floor(spec, body.contact.static_friction)
    bodies = _add_segments(spec, body)
    add_couplings(spec, body)
    _add_muscles(spec, body, bodies)
    _add_contacts(body, bodies)
    for marker in body.markers:
        bodies[marker.segment].add_site(name=marker.name, pos=list(marker.location), group=4)
    return spec
