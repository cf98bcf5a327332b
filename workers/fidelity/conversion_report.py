"""What a conversion measure found (``gaitforge bodies compare``): the result types of
:func:`~workers.fidelity.conversion.measure_conversion`, their pass criteria, and the report
as JSON and Markdown.

Units: lengths in metres inside, millimetres in the report's figures (named ``*_mm``); angles
in radians; forces in newtons.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gaitforge.workers.bodies.osim_basics import ARM_TOLERANCE_M, ARM_TOLERANCE_SHARE

PASS_RMS_M = ARM_TOLERANCE_M
"""a muscle-coordinate pair passes at this moment-arm RMS error (m) or below ..."""
PASS_SHARE = ARM_TOLERANCE_SHARE
"""... or at this share of OpenSim's peak |moment arm| over the sweep, or below"""
TARGET_PASS_SHARE = 0.95
"""the share of passing pairs a conversion aims at"""
FORCE_FLOOR = 0.05
"""a force error is relative to OpenSim's force, or to this share of the peak isometric force
where OpenSim's force is smaller (a muscle nearly slack has no meaningful relative error)"""
WORST_PAIRS = 10
"""muscle-coordinate pairs listed in the report, worst first"""


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
        return root_mean_square(self.arm_mujoco - self.arm_opensim) * 1000.0

    @property
    def arm_worst_mm(self) -> float:
        return _worst(self.arm_mujoco - self.arm_opensim) * 1000.0

    @property
    def arm_peak_mm(self) -> float:
        return float(np.max(np.abs(self.arm_opensim))) * 1000.0

    @property
    def length_rms_mm(self) -> float:
        return root_mean_square(self.length_mujoco - self.length_opensim) * 1000.0

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
    """Everything :func:`~workers.fidelity.conversion.measure_conversion` measured for one
    model."""

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


# --------------------------------------------------------------------------- helpers


def root_mean_square(values: np.ndarray) -> float:
    """RMS of ``values`` (NaN if empty)."""
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
