"""One periodic reference motion (a gait cycle) and the body state it prescribes at a phase.

A motion file holds ``N`` samples of one cycle at phases ``k/N`` (``k = 0..N-1``); the cycle is
periodic, so sample ``N`` would be sample ``0`` again. Speeds are not stored: they are the
periodic central differences of the samples (``(x[k+1] - x[k-1]) / (2 dt)``, wrapping at the
seam), so angles and speeds are consistent everywhere, the seam included. Between samples
:meth:`Motion.at` interpolates linearly (periodic).

Checked when a motion is built (see :func:`seam_problem`): all series have ``N`` samples,
``period_s > 0``, ``speed_m_s > 0``, every joint is a non-root dof of the body, every foot is
one of the body's feet, and the cycle closes: the jump across the seam (last sample to first)
is at most :data:`SEAM_FACTOR` times the largest step between neighbouring samples inside the
cycle, for the angles and for their speeds (a kink at the seam is a speed jump).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from gaitforge.workers.bodies.topology import topology_for
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, model_validator

SEAM_FACTOR = 2.0
"""A closing cycle's seam jump is at most this many times its largest inside step."""
SEAM_FLOOR = 1e-3
"""Absolute allowance (rad, m; rad/s for speeds scaled by the sample step) for near-constant
series, whose inside steps are ~0."""
LATERAL_AXIS = {"myoleg": 1}
"""Index of the lateral axis in a body's world axes (default 2: Z right, neutral bodies)."""
PELVIS_SERIES = ("pelvis_height", "pelvis_pitch", "pelvis_list", "pelvis_rotation")


class MotionProblem(Exception):
    """A motion's content is invalid: ``field`` (dotted path) and what is wrong.

    Not a ValueError on purpose: pydantic would wrap it and lose the field name.
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


@dataclass(frozen=True)
class MotionState:
    """The reference body state at one phase.

    Attributes:
        phase: in [0, 1).
        joints: rad, every tracked joint.
        joint_speeds: rad/s.
        pelvis_height: m, pelvis origin above the floor.
        pelvis_pitch, pelvis_list, pelvis_rotation: rad (OpenSim's pelvis_tilt/list/rotation).
        pelvis_angular_speed: rad/s of (pitch, list, rotation).
        pelvis_vertical_speed: m/s.
        forward_speed: m/s.
        feet_rel_pelvis: m, foot contact centroid minus pelvis origin, body's world axes.
        stance: foot on the ground.
    """

    phase: float
    joints: dict[str, float]
    joint_speeds: dict[str, float]
    pelvis_height: float
    pelvis_pitch: float
    pelvis_list: float
    pelvis_rotation: float
    pelvis_angular_speed: tuple[float, float, float]
    pelvis_vertical_speed: float
    forward_speed: float
    feet_rel_pelvis: dict[str, tuple[float, float, float]]
    stance: dict[str, bool]


def _mirror_name(name: str) -> str:
    for a, b in (("_r", "_l"), ("_l", "_r"), ("_right", "_left"), ("_left", "_right")):
        if name.endswith(a):
            return name[: -len(a)] + b
    return name


def seam_problem(x: np.ndarray) -> str | None:
    """Why the periodic series ``x`` [N] does not close, or None.

    Angles: ``|x[0] - x[N-1]| <= SEAM_FACTOR * max|x[k+1] - x[k]| + SEAM_FLOOR``. Speeds (as
    steps, i.e. speed times the sample interval): the change of step across the seam is
    bounded the same way by the largest change of step inside the cycle.
    """
    steps = np.diff(x)
    seam = x[0] - x[-1]
    bound = SEAM_FACTOR * float(np.max(np.abs(steps))) + SEAM_FLOOR
    if abs(seam) > bound:
        return (
            f"the cycle does not close: jump {seam:+.4g} from the last sample to the first, "
            f"allowed at most {bound:.4g} ({SEAM_FACTOR:g} x the largest step inside the cycle)"
        )
    kinks = np.diff(steps)
    seam_kinks = np.array([seam - steps[-1], steps[0] - seam])
    bound = SEAM_FACTOR * float(np.max(np.abs(kinks))) + SEAM_FLOOR
    if float(np.max(np.abs(seam_kinks))) > bound:
        return (
            "the cycle's speed does not close: its step changes by "
            f"{float(np.max(np.abs(seam_kinks))):.4g} across the seam, allowed at most "
            f"{bound:.4g} ({SEAM_FACTOR:g} x the largest change inside the cycle)"
        )
    return None


class Motion(BaseModel):
    """One periodic gait cycle on a body, as stored in ``data/<body>-<name>.yaml``.

    Stored fields (N samples each, phase k/N): ``joint_angles`` (rad, per joint),
    ``pelvis_height`` (m), ``pelvis_pitch``/``pelvis_list``/``pelvis_rotation`` (rad),
    ``forward_speed_offset`` (m/s, added to ``speed_m_s``), ``feet_rel_pelvis`` (m, [N, 3]
    per foot), ``stance`` (per foot).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str
    body: str
    period_s: float = Field(gt=0, description="s, one cycle (a stride)")
    speed_m_s: float = Field(gt=0, description="m/s, mean forward speed")
    source: str
    feet: list[str] = Field(min_length=1)
    joint_angles: dict[str, list[float]] = Field(min_length=1)
    pelvis_height: list[float]
    pelvis_pitch: list[float]
    pelvis_list: list[float] | None = None
    pelvis_rotation: list[float] | None = None
    forward_speed_offset: list[float] | None = None
    feet_rel_pelvis: dict[str, list[tuple[float, float, float]]]
    stance: dict[str, list[bool]]

    _table: np.ndarray = PrivateAttr()
    _speeds: np.ndarray = PrivateAttr()
    _index: dict[str, int] = PrivateAttr()
    _stance: np.ndarray = PrivateAttr()

    @model_validator(mode="after")
    def _check(self) -> Motion:
        n = len(self.pelvis_height)
        if n < 8:
            raise MotionProblem("pelvis_height", f"{n} samples; a cycle needs at least 8")
        series: dict[str, Any] = {f"joint_angles.{k}": v for k, v in self.joint_angles.items()}
        series |= {f: getattr(self, f) for f in (*PELVIS_SERIES, "forward_speed_offset")}
        series |= {f"feet_rel_pelvis.{k}": v for k, v in self.feet_rel_pelvis.items()}
        series |= {f"stance.{k}": v for k, v in self.stance.items()}
        for field, values in series.items():
            if values is not None and len(values) != n:
                raise MotionProblem(
                    field, f"{len(values)} samples, expected {n} (as pelvis_height has)"
                )
        topo = topology_for(self.body)
        for joint in self.joint_angles:
            if joint not in topo.dof_defaults:
                raise MotionProblem(
                    f"joint_angles.{joint}",
                    f"body {self.body!r} has no such joint; its joints are "
                    f"{', '.join(topo.dof_defaults)}",
                )
        for i, foot in enumerate(self.feet):
            if foot not in topo.feet:
                raise MotionProblem(
                    f"feet.{i}",
                    f"body {self.body!r} has no foot {foot!r}; its feet are {', '.join(topo.feet)}",
                )
        for group in ("feet_rel_pelvis", "stance"):
            if set(getattr(self, group)) != set(self.feet):
                raise MotionProblem(group, f"must name exactly the feet {self.feet}")
        for field in [f"joint_angles.{j}" for j in self.joint_angles] + list(PELVIS_SERIES):
            values = series[field]
            if values is not None and (why := seam_problem(np.asarray(values, float))):
                raise MotionProblem(field, why)
        self._build_tables(n)
        return self

    def _build_tables(self, n: int) -> None:
        zeros = [0.0] * n
        channels = {f"j:{k}": v for k, v in self.joint_angles.items()}
        for f in PELVIS_SERIES:
            channels[f] = getattr(self, f) or zeros
        channels["forward_speed_offset"] = self.forward_speed_offset or zeros
        for foot, xyz in self.feet_rel_pelvis.items():
            arr = np.asarray(xyz, float)
            for i in range(3):
                channels[f"f:{foot}:{i}"] = arr[:, i].tolist()
        table = np.asarray(list(channels.values()), float).T  # [N, C]
        dt = self.period_s / n
        speeds = (np.roll(table, -1, axis=0) - np.roll(table, 1, axis=0)) / (2 * dt)
        self._table = np.vstack([table, table[:1]])  # [N+1, C], periodic closure
        self._speeds = np.vstack([speeds, speeds[:1]])
        self._index = {c: i for i, c in enumerate(channels)}
        self._stance = np.asarray([self.stance[f] for f in self.feet], bool).T  # [N, F]

    @property
    def joints(self) -> list[str]:
        """Tracked non-root coordinates (the body's dof names)."""
        return list(self.joint_angles)

    @property
    def samples(self) -> int:
        """N samples over one cycle."""
        return len(self.pelvis_height)

    def at(self, phase: float) -> MotionState:
        """The reference state at ``phase`` (wrapped into [0, 1)), interpolated linearly."""
        phase = float(phase) % 1.0
        n = self.samples
        s = phase * n
        k = min(int(s), n - 1)
        w = s - k
        row = (1 - w) * self._table[k] + w * self._table[k + 1]
        vel = (1 - w) * self._speeds[k] + w * self._speeds[k + 1]
        idx = self._index
        stance_row = self._stance[round(s) % n]
        return MotionState(
            phase=phase,
            joints={j: float(row[idx[f"j:{j}"]]) for j in self.joint_angles},
            joint_speeds={j: float(vel[idx[f"j:{j}"]]) for j in self.joint_angles},
            pelvis_height=float(row[idx["pelvis_height"]]),
            pelvis_pitch=float(row[idx["pelvis_pitch"]]),
            pelvis_list=float(row[idx["pelvis_list"]]),
            pelvis_rotation=float(row[idx["pelvis_rotation"]]),
            pelvis_angular_speed=(
                float(vel[idx["pelvis_pitch"]]),
                float(vel[idx["pelvis_list"]]),
                float(vel[idx["pelvis_rotation"]]),
            ),
            pelvis_vertical_speed=float(vel[idx["pelvis_height"]]),
            forward_speed=self.speed_m_s + float(row[idx["forward_speed_offset"]]),
            feet_rel_pelvis={
                f: tuple(float(row[idx[f"f:{f}:{i}"]]) for i in range(3))  # type: ignore[misc]
                for f in self.feet
            },
            stance={f: bool(stance_row[i]) for i, f in enumerate(self.feet)},
        )

    def mirrored_state(self, state: MotionState) -> MotionState:
        """``state`` with left and right swapped.

        Leg coordinates swap names (``_r`` <-> ``_l``) and keep their values: the body's left
        side has mirrored joint axes (OpenSim's convention, MyoLeg's too), so equal values
        mean mirror-image poses. World-lateral quantities change sign: pelvis list and
        rotation (and their speeds), and the lateral coordinate of each foot.
        """
        lateral = LATERAL_AXIS.get(self.body, 2)

        def flip(v: tuple[float, float, float]) -> tuple[float, float, float]:
            out = list(v)
            out[lateral] = -out[lateral]
            return (out[0], out[1], out[2])

        pitch_speed, list_speed, rot_speed = state.pelvis_angular_speed
        return replace(
            state,
            joints={_mirror_name(k): v for k, v in state.joints.items()},
            joint_speeds={_mirror_name(k): v for k, v in state.joint_speeds.items()},
            pelvis_list=-state.pelvis_list,
            pelvis_rotation=-state.pelvis_rotation,
            pelvis_angular_speed=(pitch_speed, -list_speed, -rot_speed),
            feet_rel_pelvis={_mirror_name(k): flip(v) for k, v in state.feet_rel_pelvis.items()},
            stance={_mirror_name(k): v for k, v in state.stance.items()},
        )
