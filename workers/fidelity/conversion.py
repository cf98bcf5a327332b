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
   :data:`PASS_RMS_M` or at most :data:`PASS_SHARE` of OpenSim's peak ``|moment arm|``;
4. muscle force at rest (zero velocity): at the default pose and ``force_poses - 1`` random
   poses in the middle half of every range, each muscle at activation 1 and at OpenSim's
   minimum activation (the same value in MuJoCo), OpenSim's tendon in equilibrium: the
   tendon force on each side and the relative error (against the larger of OpenSim's force
   and :data:`FORCE_FLOOR` of the peak isometric force);
5. a relaxed drop: the root joint's coordinates (and those OpenSim locks) locked at their
   defaults, no excitation (OpenSim's muscles at their minimum activation, MuJoCo's held
   there), no contact, ``drop_s`` seconds on both simulators: the RMS
   difference of every other coordinate's trajectory (rad, or m for a slide), sampled every
   :data:`DROP_SAMPLE_S`.

Units: lengths in metres inside, millimetres in the report's figures (named ``*_mm``); angles
in radians; forces in newtons.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import mujoco
import numpy as np
import opensim
from gaitforge.workers.bodies.osim_basics import (
    ARM_TOLERANCE_M,
    ARM_TOLERANCE_SHARE,
    joints_between,
)
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.couplings import CARRIER_SUFFIX
from gaitforge.workers.sim.mujoco.lock import coupled_qpos, lock_joints
from gaitforge.workers.sim.opensim.build import quiet_opensim_log
from gaitforge.workers.spec_io import SpecError, shorten

logger = logging.getLogger(__name__)

PASS_RMS_M = ARM_TOLERANCE_M
"""a muscle-coordinate pair passes at this moment-arm RMS error (m) or below ..."""
PASS_SHARE = ARM_TOLERANCE_SHARE
"""... or at this share of OpenSim's peak |moment arm| over the sweep, or below"""
TARGET_PASS_SHARE = 0.95
"""the share of passing pairs a conversion aims at"""
FORCE_FLOOR = 0.05
"""a force error is relative to OpenSim's force, or to this share of the peak isometric force
where OpenSim's force is smaller (a muscle nearly slack has no meaningful relative error)"""
DROP_SAMPLE_S = 0.01
"""s between the samples of the relaxed drop's trajectories"""
DROP_ACCURACY = 1e-3
"""OpenSim's integrator accuracy in the relaxed drop (error-controlled Runge-Kutta-Merson)"""
DROP_MUJOCO_TIMESTEP = 0.001
"""s, MuJoCo's step in the relaxed drop (``implicitfast`` integrator)"""
WORST_PAIRS = 10
"""muscle-coordinate pairs listed in the report, worst first"""
DEFAULT_POSES = 20
DEFAULT_SWEEP_POINTS = 25
DEFAULT_FORCE_POSES = 3
DEFAULT_DROP_S = 1.0


# --------------------------------------------------------------------------- results


@dataclass
class MassRow:
    """One segment's mass on both sides, kg (NaN where a side lacks the segment)."""

    segment: str
    opensim_kg: float
    mujoco_kg: float

    @property
    def error_kg(self) -> float:
        return abs(self.mujoco_kg - self.opensim_kg)


@dataclass
class Kinematics:
    """Centre-of-mass positions over random poses.

    Attributes:
        poses: how many poses were compared.
        segments: how many segments were compared in each.
        rms_mm: RMS distance between the two simulators' centres of mass, mm, over every
            segment and pose.
        worst_mm: the largest distance, mm.
        worst_segment: the segment where it occurred.
    """

    poses: int
    segments: int
    rms_mm: float
    worst_mm: float
    worst_segment: str


@dataclass
class PairResult:
    """One muscle swept over one coordinate: arrays of shape ``[sweep_points]``.

    Attributes:
        muscle: the muscle's name.
        coordinate: the swept (free, rotational) coordinate.
        q: the coordinate's values, rad.
        length_opensim, length_mujoco: muscle-tendon length, m.
        arm_opensim, arm_mujoco: moment arm ``-dL/dq``, m (per rad); NaN where MuJoCo lacks
            the muscle or the coordinate.
    """

    muscle: str
    coordinate: str
    q: np.ndarray
    length_opensim: np.ndarray
    length_mujoco: np.ndarray
    arm_opensim: np.ndarray
    arm_mujoco: np.ndarray

    @property
    def arm_rms_mm(self) -> float:
        return _rms(self.arm_mujoco - self.arm_opensim) * 1000.0

    @property
    def arm_worst_mm(self) -> float:
        return _worst(self.arm_mujoco - self.arm_opensim) * 1000.0

    @property
    def arm_peak_mm(self) -> float:
        return float(np.max(np.abs(self.arm_opensim))) * 1000.0

    @property
    def length_rms_mm(self) -> float:
        return _rms(self.length_mujoco - self.length_opensim) * 1000.0

    @property
    def length_worst_mm(self) -> float:
        return _worst(self.length_mujoco - self.length_opensim) * 1000.0

    @property
    def allowed_mm(self) -> float:
        """The moment-arm RMS error this pair may have and pass, mm."""
        return max(PASS_RMS_M * 1000.0, PASS_SHARE * self.arm_peak_mm)

    @property
    def passed(self) -> bool:
        rms = self.arm_rms_mm
        return math.isfinite(rms) and rms <= self.allowed_mm

    def summary(self) -> dict[str, Any]:
        """The pair's figures (no curves), mm."""
        return {
            "muscle": self.muscle,
            "coordinate": self.coordinate,
            "arm_rms_mm": self.arm_rms_mm,
            "arm_worst_mm": self.arm_worst_mm,
            "arm_peak_mm": self.arm_peak_mm,
            "length_rms_mm": self.length_rms_mm,
            "length_worst_mm": self.length_worst_mm,
            "passed": self.passed,
        }

    def curves(self) -> dict[str, list[float]]:
        """The sweep itself: rad and m."""
        return {
            "q": self.q.tolist(),
            "length_opensim": self.length_opensim.tolist(),
            "length_mujoco": self.length_mujoco.tolist(),
            "arm_opensim": self.arm_opensim.tolist(),
            "arm_mujoco": self.arm_mujoco.tolist(),
        }


@dataclass
class ForceRow:
    """One muscle's tendon force at one pose and activation, N (zero velocity)."""

    muscle: str
    pose: int
    activation: float
    opensim_n: float
    mujoco_n: float
    max_isometric_n: float

    @property
    def relative_error(self) -> float:
        """``|F_mujoco - F_opensim|`` over the larger of ``|F_opensim|`` and
        :data:`FORCE_FLOOR` of the peak isometric force."""
        scale = max(abs(self.opensim_n), FORCE_FLOOR * self.max_isometric_n)
        return abs(self.mujoco_n - self.opensim_n) / scale


@dataclass
class Drop:
    """The relaxed drop on both simulators.

    Attributes:
        duration_s: simulated time, s.
        locked: coordinates held at their defaults on both sides.
        rms: each other shared coordinate's RMS trajectory difference (rad, or m for a
            slide); ``inf`` where a simulator failed.
        slides: the translational coordinates among them.
        note: what went wrong or was approximated, if anything.
    """

    duration_s: float
    locked: list[str]
    rms: dict[str, float]
    slides: list[str] = field(default_factory=list)
    note: str = ""

    @property
    def worst(self) -> tuple[str, float]:
        if not self.rms:
            return "", float("nan")
        name = max(self.rms, key=lambda k: self.rms[k])
        return name, self.rms[name]


@dataclass
class ConversionReport:
    """Everything :func:`measure_conversion` measured for one model."""

    model: str
    osim_path: str
    body: str
    masses: list[MassRow]
    kinematics: Kinematics
    pairs: list[PairResult]
    forces: list[ForceRow]
    drop: Drop | None
    notes: list[str] = field(default_factory=list)

    @property
    def pass_share(self) -> float:
        """The share of muscle-coordinate pairs whose moment arms pass (the headline)."""
        if not self.pairs:
            return float("nan")
        return sum(p.passed for p in self.pairs) / len(self.pairs)

    def worst_pairs(self, count: int = WORST_PAIRS) -> list[PairResult]:
        """The pairs furthest over (or least under) their allowance, worst first."""

        def badness(pair: PairResult) -> float:
            rms = pair.arm_rms_mm
            return math.inf if not math.isfinite(rms) else rms / pair.allowed_mm

        return sorted(self.pairs, key=badness, reverse=True)[:count]

    def force_summary(self) -> dict[str, dict[str, Any]]:
        """Per activation level (``active``: 1, ``passive``: the minimum): median and worst
        relative error and the muscle of the worst."""
        summary: dict[str, dict[str, Any]] = {}
        for label, rows in (
            ("active", [r for r in self.forces if r.activation == 1.0]),
            ("passive", [r for r in self.forces if r.activation < 1.0]),
        ):
            finite = [r for r in rows if math.isfinite(r.relative_error)]
            if not finite:
                summary[label] = {"median": math.nan, "worst": math.nan, "muscle": "", "n": 0}
                continue
            worst = max(finite, key=lambda r: r.relative_error)
            summary[label] = {
                "median": float(np.median([r.relative_error for r in finite])),
                "worst": worst.relative_error,
                "muscle": worst.muscle,
                "n": len(finite),
                "failed": len(rows) - len(finite),
            }
        return summary

    def summary(self) -> dict[str, Any]:
        """The headline figures, JSON-ready (mm, kg, rad)."""
        total_osim = math.fsum(m.opensim_kg for m in self.masses if math.isfinite(m.opensim_kg))
        total_mj = math.fsum(m.mujoco_kg for m in self.masses if math.isfinite(m.mujoco_kg))
        worst_mass = max(self.masses, key=lambda m: _nan_last(m.error_kg), default=None)
        arms = np.array([p.arm_rms_mm for p in self.pairs]) if self.pairs else np.zeros(0)
        lengths = np.array([p.length_rms_mm for p in self.pairs]) if self.pairs else np.zeros(0)
        drop_coordinate, drop_rms = self.drop.worst if self.drop else ("", math.nan)
        return {
            "total_mass_opensim_kg": total_osim,
            "total_mass_mujoco_kg": total_mj,
            "worst_segment_mass_error_kg": worst_mass.error_kg if worst_mass else math.nan,
            "worst_segment_mass": worst_mass.segment if worst_mass else "",
            "com_rms_mm": self.kinematics.rms_mm,
            "com_worst_mm": self.kinematics.worst_mm,
            "com_worst_segment": self.kinematics.worst_segment,
            "pairs": len(self.pairs),
            "pairs_passed": sum(p.passed for p in self.pairs),
            "pass_share": self.pass_share,
            "target_pass_share": TARGET_PASS_SHARE,
            "arm_rms_median_mm": _nan_median(arms),
            "length_rms_median_mm": _nan_median(lengths),
            "length_worst_mm": max((p.length_worst_mm for p in self.pairs), default=math.nan),
            "force": self.force_summary(),
            "drop_worst_coordinate": drop_coordinate,
            "drop_worst_rms": drop_rms,
        }

    def to_json(self) -> dict[str, Any]:
        """Everything but the sweeps' curves (those of the worst pair only), JSON-ready:
        non-finite numbers are ``None``."""
        worst = self.worst_pairs(1)
        return _finite_or_none(
            {
                "model": self.model,
                "osim_path": self.osim_path,
                "body": self.body,
                "summary": self.summary(),
                "masses": [
                    {"segment": m.segment, "opensim_kg": m.opensim_kg, "mujoco_kg": m.mujoco_kg}
                    for m in self.masses
                ],
                "kinematics": vars(self.kinematics),
                "pairs": [p.summary() for p in self.pairs],
                "worst_pair_curves": worst[0].curves() if worst else None,
                "forces": [
                    {
                        "muscle": r.muscle,
                        "pose": r.pose,
                        "activation": r.activation,
                        "opensim_n": r.opensim_n,
                        "mujoco_n": r.mujoco_n,
                        "relative_error": r.relative_error,
                    }
                    for r in self.forces
                ],
                "drop": None if self.drop is None else vars(self.drop),
                "notes": self.notes,
            }
        )

    def markdown(self, worst: int = WORST_PAIRS) -> str:
        """A summary table, then the ``worst`` muscle-coordinate pairs, then the notes."""
        s = self.summary()
        force = s["force"]
        lines = [
            f"## {self.model}: OpenSim against MuJoCo ({self.body})",
            "",
            "| measure | value |",
            "| --- | --- |",
            f"| total mass, OpenSim / MuJoCo | {s['total_mass_opensim_kg']:.3f} / "
            f"{s['total_mass_mujoco_kg']:.3f} kg |",
            f"| worst segment mass error | {s['worst_segment_mass_error_kg']:.4f} kg "
            f"({s['worst_segment_mass']}) |",
            f"| centre-of-mass error over {self.kinematics.poses} poses, "
            f"{self.kinematics.segments} segments | RMS {s['com_rms_mm']:.2f} mm, worst "
            f"{s['com_worst_mm']:.2f} mm ({s['com_worst_segment']}) |",
            f"| moment-arm pairs passing (RMS <= {PASS_RMS_M * 1000:g} mm or "
            f"{PASS_SHARE:.0%} of peak) | **{s['pass_share']:.1%}** ({s['pairs_passed']}/"
            f"{s['pairs']}; target {TARGET_PASS_SHARE:.0%}) |",
            f"| moment-arm RMS error, median pair | {s['arm_rms_median_mm']:.2f} mm |",
            f"| muscle-tendon length RMS error, median pair | {s['length_rms_median_mm']:.2f} mm "
            f"(worst {s['length_worst_mm']:.1f} mm) |",
        ]
        for label, what in (("active", "activation 1"), ("passive", "minimum activation")):
            f = force[label]
            failed = f" ({f['failed']} not computed)" if f.get("failed") else ""
            lines.append(
                f"| tendon force at {what}, relative error | median {f['median']:.1%}, worst "
                f"{f['worst']:.1%} ({f['muscle']}){failed} |"
            )
        if self.drop is not None:
            name, rms = self.drop.worst
            angles = [v for k, v in self.drop.rms.items() if k not in self.drop.slides]
            median = float(np.median(angles)) if angles else math.nan
            lines.append(
                f"| relaxed drop {self.drop.duration_s:g} s ({len(self.drop.locked)} "
                "coordinates locked), RMS coordinate difference | worst "
                f"{_angle_or_length(rms, name in self.drop.slides)} ({name or 'none'}), median "
                f"angle {_angle_or_length(median, False)} |"
            )
        lines += [
            "",
            f"Worst {min(worst, len(self.pairs))} muscle-coordinate pairs (moment arm, mm):",
            "",
            "| muscle | coordinate | RMS | worst | peak | allowed | length RMS | pass |",
            "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |",
        ]
        for p in self.worst_pairs(worst):
            lines.append(
                f"| {p.muscle} | {p.coordinate} | {p.arm_rms_mm:.2f} | {p.arm_worst_mm:.2f} | "
                f"{p.arm_peak_mm:.1f} | {p.allowed_mm:.2f} | {p.length_rms_mm:.2f} | "
                f"{'yes' if p.passed else 'NO'} |"
            )
        if self.notes or (self.drop is not None and self.drop.note):
            lines += ["", "Notes:", ""]
            lines += [f"- {n}" for n in self.notes]
            if self.drop is not None and self.drop.note:
                lines.append(f"- relaxed drop: {self.drop.note}")
        return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- OpenSim


def load_opensim_model(path: Path) -> Any:
    """``opensim.Model`` read from ``path``, OpenSim's log silenced.

    Raises:
        SpecError: the file is missing, unreadable, not well-formed XML or not an OpenSim
            model (one line naming it).
    """
    quiet_opensim_log()
    path = Path(path)
    if not path.exists():
        raise SpecError(f"{path}: file not found")
    if not path.is_file():
        raise SpecError(f"{path}: not a file")
    try:
        root = ElementTree.parse(path).getroot()
    except OSError as exc:
        raise SpecError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except ElementTree.ParseError as exc:
        line, column = exc.position
        raise SpecError(f"{path}: line {line}, column {column}: not well-formed XML") from None
    if root.tag != "OpenSimDocument" or root.find("Model") is None:
        raise SpecError(f"{path}: not an OpenSim model (no <OpenSimDocument><Model>)")
    try:
        return opensim.Model(str(path))
    except Exception as exc:  # OpenSim raises RuntimeError with a multi-line message
        reason = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        raise SpecError(f"{path}: OpenSim cannot load the model: {shorten(reason, 300)}") from None


class OpenSimSide:
    """The original model, posed by coordinate name.

    Every coordinate is unlocked unless named in ``locked`` (those are locked at their
    defaults), so that any pose can be set."""

    def __init__(self, path: Path, locked: frozenset[str] = frozenset()) -> None:
        self.model = load_opensim_model(path)
        coordinate_set = self.model.getCoordinateSet()
        self.default_locked: set[str] = set()  # the coordinates the file locks
        for i in range(coordinate_set.getSize()):
            coordinate = coordinate_set.get(i)
            if coordinate.getDefaultLocked():
                self.default_locked.add(coordinate.getName())
            coordinate.setDefaultLocked(coordinate.getName() in locked)
        self.state = self.model.initSystem()
        self.coordinates = {
            coordinate_set.get(i).getName(): coordinate_set.get(i)
            for i in range(coordinate_set.getSize())
        }
        self.couplers: list[tuple[str, list[str], Any]] = []
        constraints = self.model.getConstraintSet()
        for i in range(constraints.getSize()):
            coupler = opensim.CoordinateCouplerConstraint.safeDownCast(constraints.get(i))
            if coupler is None or not coupler.get_isEnforced():
                continue
            names = coupler.getIndependentCoordinateNames()
            self.couplers.append(
                (
                    coupler.getDependentCoordinateName(),
                    [names.get(k) for k in range(names.getSize())],
                    coupler.getFunction(),
                )
            )
        dependent = {d for d, _, _ in self.couplers}
        self.free = [name for name in self.coordinates if name not in dependent]
        self.driver_of = {d: independents[0] for d, independents, _ in self.couplers}
        muscles = self.model.getMuscles()
        self.muscles = {muscles.get(i).getName(): muscles.get(i) for i in range(muscles.getSize())}
        bodies = self.model.getBodySet()
        self.bodies = {bodies.get(i).getName(): bodies.get(i) for i in range(bodies.getSize())}

    def defaults(self) -> dict[str, float]:
        """Each free coordinate's default value (rad or m)."""
        return {name: self.coordinates[name].getDefaultValue() for name in self.free}

    def ranges(self) -> dict[str, tuple[float, float]]:
        """Each free coordinate's range (rad or m)."""
        return {
            name: (self.coordinates[name].getRangeMin(), self.coordinates[name].getRangeMax())
            for name in self.free
        }

    def rotational(self, name: str) -> bool:
        return self.coordinates[name].getMotionType() == opensim.Coordinate.Rotational

    def set_pose(self, values: Mapping[str, float]) -> None:
        """Free coordinates to ``values`` (rad, m), coupled ones after them; positions
        realised."""
        for name, value in values.items():
            if not self.coordinates[name].getLocked(self.state):
                self.coordinates[name].setValue(self.state, float(value), False)
        for dependent, independents, function in self.couplers:
            x = opensim.Vector(len(independents), 0.0)
            for k, name in enumerate(independents):
                x.set(k, self.coordinates[name].getValue(self.state))
            self.coordinates[dependent].setValue(self.state, function.calcValue(x), False)
        self.model.realizePosition(self.state)

    def centres_of_mass(self, names: list[str]) -> np.ndarray:
        """[len(names), 3] world positions of the segments' centres of mass, m."""
        return np.array(
            [
                self.bodies[n]
                .findStationLocationInGround(self.state, self.bodies[n].getMassCenter())
                .to_numpy()
                for n in names
            ]
        )

    def spanned(self) -> dict[str, list[str]]:
        """Each muscle's free coordinates: those of the joints between the bodies its path
        points (and moving or conditional points' coordinates) attach to, a coupled
        coordinate replaced by its driver."""
        spans: dict[str, list[str]] = {}
        for name, muscle in self.muscles.items():
            points = muscle.getGeometryPath().getPathPointSet()
            segments: set[str] = set()
            extra: list[str] = []
            for k in range(points.getSize()):
                point = points.get(k)
                segments.add(point.getParentFrame().findBaseFrame().getName())
                moving = opensim.MovingPathPoint.safeDownCast(point)
                if moving is not None:
                    extra += [moving.getXCoordinate().getName()]
                conditional = opensim.ConditionalPathPoint.safeDownCast(point)
                if conditional is not None:
                    extra += [conditional.getCoordinate().getName()]
            crossed = [
                joint.get_coordinates(k).getName()
                for joint in joints_between(self.model, segments)
                for k in range(joint.numCoordinates())
            ]
            free = [self.driver_of.get(c, c) for c in [*crossed, *extra]]
            spans[name] = [c for c in dict.fromkeys(free) if c in self.free]
        return spans

    def tendon_forces(self, activation: float | None) -> dict[str, float]:
        """Each muscle's tendon force (N) at zero velocity, its fibre in equilibrium, all at
        ``activation`` (None: each at its own minimum); NaN where equilibrium fails."""
        for name, muscle in self.muscles.items():
            level = self.minimum_activation(name) if activation is None else activation
            muscle.setActivation(self.state, level)
        self.state.updU().setToZero()
        forces: dict[str, float] = {}
        failed: set[str] = set()
        for name, muscle in self.muscles.items():
            try:
                muscle.computeEquilibrium(self.state)
            except Exception as exc:  # OpenSim raises RuntimeError when it cannot converge
                logger.info("OpenSim: %s: no fibre equilibrium: %s", name, exc)
                failed.add(name)
        self.model.realizeDynamics(self.state)
        for name, muscle in self.muscles.items():
            forces[name] = math.nan if name in failed else muscle.getTendonForce(self.state)
        return forces

    def minimum_activation(self, name: str) -> float:
        """The muscle's minimum activation (Millard's and Thelen's property; 0.01 else)."""
        muscle = self.muscles[name]
        for kind in (opensim.Millard2012EquilibriumMuscle, opensim.Thelen2003Muscle):
            concrete = kind.safeDownCast(muscle)
            if concrete is not None:
                return float(concrete.get_minimum_activation())
        return 0.01


# --------------------------------------------------------------------------- MuJoCo


class MujocoSide:
    """The model built from the body, posed by joint name."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.joints = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j): j for j in range(model.njnt)
        }
        self.tendons = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, t): t for t in range(model.ntendon)
        }
        self.actuators = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a): a for a in range(model.nu)
        }
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]
        self.bodies = {  # a moving point's carrier is part of its muscle's path, not a segment
            name: b for b, name in enumerate(names) if not name.endswith(CARRIER_SUFFIX)
        }
        self._jacobian = np.zeros((model.ntendon, model.nv))

    def set_pose(self, values: Mapping[str, float]) -> None:
        """Joints named in ``values`` to them (rad, m), the others at ``qpos0``, coupled ones
        after their drivers; positions and tendons computed; velocities zero."""
        qpos = self.model.qpos0.copy()
        for name, value in values.items():
            joint = self.joints.get(name)
            if joint is not None:
                qpos[self.model.jnt_qposadr[joint]] = value
        self.data.qpos[:] = coupled_qpos(self.model, qpos)
        self.data.qvel[:] = 0.0
        mujoco.mj_fwdPosition(self.model, self.data)

    def centres_of_mass(self, names: list[str]) -> np.ndarray:
        """[len(names), 3] world positions of the bodies' centres of mass, m."""
        return np.array([self.data.xipos[self.bodies[n]] for n in names])

    def lengths(self) -> np.ndarray:
        """[ntendon] tendon lengths at the current pose, m."""
        return np.array(self.data.ten_length)

    def moment_arms(self, coordinate: str) -> np.ndarray:
        """[ntendon] ``-dL/dq`` about the free joint ``coordinate`` at the current pose, the
        joints it drives folded in (m per rad, or m/m)."""
        mujoco.mju_sparse2dense(
            self._jacobian,
            self.data.ten_J,
            self.model.ten_J_rownnz,
            self.model.ten_J_rowadr,
            self.model.ten_J_colind,
        )
        return -(self._jacobian @ self._chain(coordinate))

    def _chain(self, coordinate: str) -> np.ndarray:
        """[nv] ``dq_dof / dq_coordinate`` at the current pose: 1 at the coordinate's own dof,
        the polynomial's slope at every joint an equality couples to it."""
        model = self.model
        driver = self.joints[coordinate]
        column = np.zeros(model.nv)
        column[model.jnt_dofadr[driver]] = 1.0
        for i in range(model.neq):
            if model.eq_type[i] != mujoco.mjtEq.mjEQ_JOINT or model.eq_obj2id[i] != driver:
                continue
            coefficients = model.eq_data[i, :5]
            x = self.data.qpos[model.jnt_qposadr[driver]] - model.qpos0[model.jnt_qposadr[driver]]
            slope = np.polyval(np.polyder(coefficients[::-1]), x)
            column[model.jnt_dofadr[model.eq_obj1id[i]]] += slope
        return column

    def tendon_forces(self, activations: Mapping[str, float]) -> dict[str, float]:
        """Each muscle actuator's tendon force (N, pulling positive) at the current pose,
        zero velocity, activation as given by name."""
        for name, level in activations.items():
            actuator = self.actuators.get(name)
            if actuator is None:
                continue
            address = self.model.actuator_actadr[actuator]
            if address >= 0:
                self.data.act[address] = level
            self.data.ctrl[actuator] = level
        mujoco.mj_forward(self.model, self.data)
        return {
            name: -float(self.data.actuator_force[self.actuators[name]])
            for name in activations
            if name in self.actuators
        }


# --------------------------------------------------------------------------- measures


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
        report.drop = _drop(osim_path, body, opensim_side, drop_s)
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
        rms_mm=_rms(distances) * 1000.0,
        worst_mm=float(distances[worst]) * 1000.0,
        worst_segment=names[worst[1]],
    )


@dataclass
class CoordinateSweep:
    """One coordinate swept over its range, the others at their defaults: ``q`` [points]
    (rad), OpenSim's path lengths and moment arms (m) [muscles, points] and MuJoCo's of the
    tendons swept [tendons, points] (NaN where a tendon is missing or MuJoCo lacks the
    coordinate)."""

    q: np.ndarray
    length_osim: np.ndarray
    arm_osim: np.ndarray
    length_mujoco: np.ndarray
    arm_mujoco: np.ndarray


def sweep_coordinate(
    osim: OpenSimSide,
    mj: MujocoSide,
    coordinate: str,
    muscles: list[str],
    rows: list[int | None],
    points: int,
) -> CoordinateSweep:
    """OpenSim's ``muscles`` and MuJoCo's tendon ``rows`` (None: no tendon) over ``points``
    values of rotational ``coordinate`` across its range."""
    q = np.linspace(*osim.ranges()[coordinate], points)
    defaults = osim.defaults()
    length_os, arm_os = np.zeros((len(muscles), points)), np.zeros((len(muscles), points))
    length_mj = np.full((len(rows), points), math.nan)
    arm_mj = np.full((len(rows), points), math.nan)
    for k, value in enumerate(q):
        pose = {**defaults, coordinate: float(value)}
        osim.set_pose(pose)
        for i, muscle in enumerate(muscles):
            path = osim.muscles[muscle]
            length_os[i, k] = path.getLength(osim.state)
            arm_os[i, k] = path.computeMomentArm(osim.state, osim.coordinates[coordinate])
        if coordinate not in mj.joints:
            continue
        mj.set_pose(pose)
        lengths, arms = mj.lengths(), mj.moment_arms(coordinate)
        for i, row in enumerate(rows):
            if row is not None:
                length_mj[i, k], arm_mj[i, k] = lengths[row], arms[row]
    return CoordinateSweep(q, length_os, arm_os, length_mj, arm_mj)


def sweep_pairs(
    osim: OpenSimSide,
    mj: MujocoSide,
    points: int,
    notes: list[str],
    only: list[str] | None = None,
) -> list[PairResult]:
    """Every muscle (or those in ``only``) over every rotational free coordinate it spans
    (OpenSim's topology)."""
    spans = osim.spanned()
    if only is not None:
        spans = {m: c for m, c in spans.items() if m in only}
    slides = sorted({c for cs in spans.values() for c in cs if not osim.rotational(c)})
    if slides:
        notes.append(f"translational coordinates not swept: {', '.join(slides)}")
    absent = [m for m in spans if m not in mj.tendons]
    if absent:
        notes.append(f"muscles without a MuJoCo tendon (their pairs fail): {', '.join(absent)}")
    by_coordinate: dict[str, list[str]] = {}
    for muscle, coordinates in spans.items():
        for c in coordinates:
            if osim.rotational(c):
                by_coordinate.setdefault(c, []).append(muscle)
    pairs: list[PairResult] = []
    for coordinate, muscles in by_coordinate.items():
        rows = [mj.tendons.get(m) for m in muscles]
        sweep = sweep_coordinate(osim, mj, coordinate, muscles, rows, points)
        pairs += [
            PairResult(
                muscle,
                coordinate,
                sweep.q,
                sweep.length_osim[i],
                sweep.length_mujoco[i],
                sweep.arm_osim[i],
                sweep.arm_mujoco[i],
            )
            for i, muscle in enumerate(muscles)
        ]
    muscle_order = {name: i for i, name in enumerate(osim.muscles)}
    coordinate_order = {name: i for i, name in enumerate(osim.coordinates)}
    pairs.sort(key=lambda p: (muscle_order[p.muscle], coordinate_order[p.coordinate]))
    return pairs


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


def _drop(osim_path: Path, body: Body, posed: OpenSimSide, duration: float) -> Drop:
    """Both simulators let go from the default pose, the root and OpenSim's locked
    coordinates held, no excitation, no contact (MuJoCo's contacts disabled)."""
    root = [d.name for d in body.ordered_joints()[0].dofs]
    defaults = posed.defaults()
    wanted = {c for c in [*root, *posed.default_locked] if c in posed.free}
    spec = build_spec(body)
    note = ""
    try:
        removed = lock_joints(spec, {c: defaults[c] for c in wanted if c in body.dof_names})
    except ValueError as exc:  # a locked joint after a free one in its body
        note = f"OpenSim's locked coordinates left free on both sides ({exc})"
        wanted = {c for c in root if c in posed.free}
        spec = build_spec(body)
        removed = lock_joints(spec, {c: defaults[c] for c in wanted})
    absent = {c for c in posed.free if c not in body.dof_names}
    locked = frozenset(wanted | absent)
    model = spec.compile()
    model.opt.timestep = DROP_MUJOCO_TIMESTEP
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    compared = [c for c in posed.free if c not in locked and c not in removed]
    samples = max(1, round(duration / DROP_SAMPLE_S))
    minimum = {name: posed.minimum_activation(name) for name in posed.muscles}
    trajectory_mj = _drop_mujoco(model, defaults, minimum, compared, samples)
    trajectory_os, failure = _drop_opensim(osim_path, locked, compared, samples)
    if failure:
        note = "; ".join(n for n in (note, f"OpenSim failed: {failure}") if n)
    rms = {
        c: _rms(trajectory_mj[:, i] - trajectory_os[:, i])
        if np.all(np.isfinite(trajectory_mj[:, i])) and np.all(np.isfinite(trajectory_os[:, i]))
        else math.inf
        for i, c in enumerate(compared)
    }
    slides = [c for c in compared if not posed.rotational(c)]
    return Drop(samples * DROP_SAMPLE_S, sorted(locked), rms, slides, note)


def _drop_mujoco(
    model: mujoco.MjModel,
    defaults: Mapping[str, float],
    activations: Mapping[str, float],
    compared: list[str],
    samples: int,
) -> np.ndarray:
    """[samples, len(compared)] MuJoCo's coordinates after each :data:`DROP_SAMPLE_S`, each
    muscle's control and activation held at ``activations`` (OpenSim's minimum: what its
    activation stays at without excitation)."""
    side = MujocoSide(model)
    side.set_pose(defaults)
    side.data.act[:] = 0.0
    side.data.ctrl[:] = 0.0
    side.tendon_forces(activations)  # sets act and ctrl by muscle name
    addresses = [model.jnt_qposadr[side.joints[c]] for c in compared]
    steps = max(1, round(DROP_SAMPLE_S / model.opt.timestep))
    out = np.full((samples, len(compared)), math.nan)
    for k in range(samples):
        mujoco.mj_step(model, side.data, nstep=steps)
        if not np.all(np.isfinite(side.data.qpos)):
            logger.info("MuJoCo: the relaxed drop diverged at sample %d", k)
            break
        out[k] = side.data.qpos[addresses]
    return out


def _drop_opensim(
    path: Path, locked: frozenset[str], compared: list[str], samples: int
) -> tuple[np.ndarray, str]:
    """[samples, len(compared)] OpenSim's coordinates after each :data:`DROP_SAMPLE_S`,
    muscles at their minimum activation, fibres in equilibrium at the start; and why it
    stopped early ("" if it did not)."""
    side = OpenSimSide(path, locked)
    side.set_pose(side.defaults())
    for name, muscle in side.muscles.items():
        muscle.setActivation(side.state, side.minimum_activation(name))
    out = np.full((samples, len(compared)), math.nan)
    try:
        side.model.equilibrateMuscles(side.state)
        manager = opensim.Manager(side.model)
        manager.setWriteToStorage(False)
        manager.setPerformAnalyses(False)
        manager.setIntegratorAccuracy(DROP_ACCURACY)
        side.state.setTime(0.0)
        manager.initialize(side.state)
        for k in range(samples):
            state = manager.integrate((k + 1) * DROP_SAMPLE_S)
            out[k] = [side.coordinates[c].getValue(state) for c in compared]
    except Exception as exc:  # OpenSim raises RuntimeError when integration fails
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return out, first
    return out, ""


# --------------------------------------------------------------------------- helpers


def _rms(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def _worst(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.max(np.abs(values))) if values.size else math.nan


def _nan_median(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.median(finite)) if finite.size else math.nan


def _nan_last(value: float) -> float:
    return value if math.isfinite(value) else -math.inf


def _angle_or_length(value: float, slide: bool) -> str:
    """An RMS difference (rad, or m for a slide) in the report: degrees, or mm."""
    if not math.isfinite(value):
        return str(value)
    if slide:
        return f"{value * 1000:.1f} mm"
    return f"{math.degrees(value):.2f} deg"


def _finite_or_none(value: Any) -> Any:
    """``value`` with numpy scalars as Python numbers and non-finite floats as ``None``."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
