"""How faithful a converted body is: the original OpenSim model against the MuJoCo model
built from the body (``gaitforge bodies compare``).

Both simulators are posed by coordinate name (a body keeps OpenSim's segment, coordinate and
muscle names), every free coordinate at the same value, coupled ones following their drivers
(OpenSim's ``CoordinateCouplerConstraint`` functions; MuJoCo's joint equalities). The OpenSim
side unlocks every coordinate for the geometric measures (a locked coordinate would not take
a pose). Five measures:

1. segment masses, each and in total (kg);
2. kinematics: at ``poses`` random poses (each free coordinate uniform in its OpenSim range)
   the world position of every segment's centre of mass (OpenSim
   ``findStationLocationInGround`` of the mass centre, MuJoCo ``xipos``): RMS and worst
   distance, mm;
3. muscle geometry: for each muscle and each rotational free coordinate it spans in the
   OpenSim model (a coordinate coupled to another counts as its driver), the coordinate swept
   over its range in ``sweep_points`` steps, the others at their defaults: muscle-tendon length
   (``getLength``, ``ten_length``) and moment arm (``computeMomentArm``; MuJoCo's ``-dL/dq``
   from ``ten_J`` chained through the coupled joints, ``dL/dq_driver = sum_j dL/dq_j
   dq_j/dq_driver``). A pair passes when its moment-arm RMS error is at most
   ``conversion_report.PASS_RMS_M`` or at most ``conversion_report.PASS_SHARE`` of OpenSim's
   peak ``|moment arm|``;
4. muscle force at rest (zero velocity): at the default pose and ``force_poses - 1`` random
   poses in the middle half of every range, each muscle at activation 1 and at OpenSim's
   minimum activation (the same value in MuJoCo), OpenSim's tendon in equilibrium: the
   tendon force on each side and the relative error (against the larger of OpenSim's force
   and ``conversion_report.FORCE_FLOOR`` of the peak isometric force);
5. a relaxed drop: the root joint's coordinates (and those OpenSim locks) locked at their
   defaults, no excitation (OpenSim's muscles at their minimum activation, MuJoCo's held
   there), no contact, ``drop_s`` seconds on both simulators: the RMS
   difference of every other coordinate's trajectory (rad, or m for a slide), sampled every
   ``conversion_drop.DROP_SAMPLE_S``.

Measures 1, 2 and 4 are here, 3 is ``conversion_sweeps`` and 5 ``conversion_drop``; the two
simulators, posed by coordinate name, are ``conversion_sides``; what the measures return and
the report as JSON and Markdown, ``conversion_report``.

Units: lengths in metres inside, millimetres in the report's figures (named ``*_mm``); angles
in radians; forces in newtons.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.fidelity.conversion_drop import relaxed_drop
from gaitforge.workers.fidelity.conversion_report import (
    ConversionReport,
    ForceRow,
    Kinematics,
    MassRow,
    root_mean_square,
)
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, OpenSimSide
from gaitforge.workers.fidelity.conversion_sweeps import DEFAULT_SWEEP_POINTS, sweep_pairs
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.spec_io import SpecError

logger = logging.getLogger(__name__)

DEFAULT_POSES = 20
DEFAULT_FORCE_POSES = 3
DEFAULT_DROP_S = 1.0


def measure_conversion(
    osim_path: Path,
    body: Body,
    *,
    poses: int = DEFAULT_POSES,
    sweep_points: int = DEFAULT_SWEEP_POINTS,
    force_poses: int = DEFAULT_FORCE_POSES,
    drop_s: float = DEFAULT_DROP_S,
    seed: int = 0,
) -> ConversionReport:
    """Compare the OpenSim model at ``osim_path`` with the MuJoCo model built from ``body``.

    Args:
        osim_path: the original ``.osim`` file.
        body: the converted body (names as OpenSim's).
        poses: random poses of the kinematic comparison (at least 1).
        sweep_points: coordinate values of each muscle-coordinate sweep (at least 2).
        force_poses: poses of the force comparison, the default pose first (at least 1).
        drop_s: seconds of the relaxed drop (0: none).
        seed: seed of the random poses.

    Returns:
        The report (see the module's docstring for what it holds).

    Raises:
        SpecError: the file is missing or not an OpenSim model, or the body does not build
            into a MuJoCo model.
    """
    osim_path = Path(osim_path)
    if poses < 1 or sweep_points < 2 or force_poses < 1 or drop_s < 0:
        raise ValueError("poses >= 1, sweep_points >= 2, force_poses >= 1 and drop_s >= 0")
    opensim_side = OpenSimSide(osim_path)
    try:
        mujoco_model = build_spec(body).compile()
    except ValueError as exc:
        reason = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        raise SpecError(f"body {body.name!r}: does not build a MuJoCo model: {reason}") from None
    mujoco_side = MujocoSide(mujoco_model)
    notes: list[str] = []
    missing = [c for c in opensim_side.free if c not in mujoco_side.joints]
    if missing:
        notes.append(f"free coordinates without a MuJoCo joint: {', '.join(missing)}")
    rng = np.random.default_rng(seed)
    report = ConversionReport(
        model=osim_path.stem,
        osim_path=str(osim_path),
        body=body.name,
        masses=_masses(opensim_side, mujoco_side, notes),
        kinematics=_kinematics(opensim_side, mujoco_side, poses, rng),
        pairs=sweep_pairs(opensim_side, mujoco_side, sweep_points, notes),
        forces=_forces(opensim_side, mujoco_side, force_poses, rng),
        drop=None,
        notes=notes,
    )
    if drop_s > 0:
        report.drop = relaxed_drop(osim_path, body, opensim_side, drop_s)
    logger.info(
        "%s: %.1f %% of %d muscle-coordinate pairs pass",
        report.model,
        100 * report.pass_share,
        len(report.pairs),
    )
    return report


def _masses(osim: OpenSimSide, mj: MujocoSide, notes: list[str]) -> list[MassRow]:
    rows = [
        MassRow(
            name,
            body.getMass(),
            float(mj.model.body_mass[mj.bodies[name]]) if name in mj.bodies else math.nan,
        )
        for name, body in osim.bodies.items()
    ]
    extra = [n for n in mj.bodies if n != "world" and n not in osim.bodies]
    rows += [MassRow(n, math.nan, float(mj.model.body_mass[mj.bodies[n]])) for n in extra]
    absent = [r.segment for r in rows if not math.isfinite(r.mujoco_kg)]
    if absent:
        notes.append(f"OpenSim bodies without a MuJoCo body: {', '.join(absent)}")
    if extra:
        notes.append(f"MuJoCo bodies not in the OpenSim model: {', '.join(extra)}")
    return rows


def _random_pose(
    ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator, middle: float = 1.0
) -> dict[str, float]:
    """Each coordinate uniform in the central ``middle`` share of its range."""
    pose = {}
    for name, (lo, hi) in ranges.items():
        margin = 0.5 * (1.0 - middle) * (hi - lo)
        pose[name] = float(rng.uniform(lo + margin, hi - margin))
    return pose


def _kinematics(
    osim: OpenSimSide, mj: MujocoSide, poses: int, rng: np.random.Generator
) -> Kinematics:
    names = [n for n in osim.bodies if n in mj.bodies]
    distances = np.zeros((poses, len(names)))
    ranges = osim.ranges()
    for p in range(poses):
        pose = _random_pose(ranges, rng)
        osim.set_pose(pose)
        mj.set_pose(pose)
        difference = osim.centres_of_mass(names) - mj.centres_of_mass(names)
        distances[p] = np.linalg.norm(difference, axis=1)
    if not names:
        return Kinematics(poses, 0, math.nan, math.nan, "")
    worst = np.unravel_index(int(np.argmax(distances)), distances.shape)
    return Kinematics(
        poses=poses,
        segments=len(names),
        rms_mm=root_mean_square(distances) * 1000.0,
        worst_mm=float(distances[worst]) * 1000.0,
        worst_segment=names[worst[1]],
    )


def _forces(
    osim: OpenSimSide, mj: MujocoSide, poses: int, rng: np.random.Generator
) -> list[ForceRow]:
    """Default pose, then random ones in the middle half of the ranges; activation 1 and the
    minimum."""
    defaults, ranges = osim.defaults(), osim.ranges()
    rows: list[ForceRow] = []
    for p in range(poses):
        pose = defaults if p == 0 else _random_pose(ranges, rng, middle=0.5)
        for activation in (1.0, None):
            osim.set_pose(pose)
            forces_os = osim.tendon_forces(activation)
            levels = {
                name: osim.minimum_activation(name) if activation is None else activation
                for name in osim.muscles
            }
            mj.set_pose(pose)
            forces_mj = mj.tendon_forces(levels)
            rows += [
                ForceRow(
                    name,
                    p,
                    levels[name],
                    forces_os[name],
                    forces_mj.get(name, math.nan),
                    osim.muscles[name].getMaxIsometricForce(),
                )
                for name in osim.muscles
            ]
    return rows
