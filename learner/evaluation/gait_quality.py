"""Gait quality of an episode beside a recorded gait: what a biomechanist reads first.

From one episode's steps (:class:`GaitTrace`, recorded by :class:`GaitRecorder`, an episode
observer) and a recorded gait cycle (``workers.motions.Motion``, one stride from right heel
strike, ``samples`` points), :func:`gait_quality` gives:

- **strides**: from one right heel strike to the next. A foot is in stance while its ground
  force is at least ``CONTACT_FRACTION`` of body weight, and a heel strike ends a swing of at
  least ``MIN_SWING_S`` (shorter gaps are bounces); only whole strides between two strikes
  count;
- **joint angles over the gait cycle**: each stride's angles resampled on 0-100 % of it (at
  the recording's sample points), their mean and standard deviation per joint, and the RMS
  of the mean against the recording (rad);
- **stride length** (m, the pelvis's forward travel over a stride), **stride time** (s) and
  **cadence** (steps per minute, two steps a stride);
- **symmetry**: the step time from a right heel strike to the next left one against the left
  to right one, ``|a - b| / mean(a, b)`` (0: symmetric);
- **foot clearance**: per foot, the highest point of each swing (no ground force) above the
  foot's median height in stance, averaged over the swings (m);
- **legs through each other** (MuJoCo, bodies with MyoSuite's leg-on-leg contact geoms:
  thighs, shanks, feet): the closest any such pair of geoms came (m, signed: below 0 they
  interpenetrate, whether or not the scene lets them collide) and the share of steps where a
  pair interpenetrated.

:func:`plot_gait` draws the cycle: one panel per joint, the episode's mean with a band of
one standard deviation, and the recording.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from gaitforge.workers.env import GRAVITY
from gaitforge.workers.episode import Observer
from gaitforge.workers.sim.mujoco.mjcf_models import leg_contact_pairs

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv
    from gaitforge.workers.motions import Motion

CONTACT_FRACTION = 0.05
"""A foot is in stance while its ground force is at least this share of body weight."""
MIN_SWING_S = 0.15
"""s; a foot off the ground for less is still in stance (a bounce at touchdown, contact chatter
between the heel's and the toe's spheres)."""
RIGHT, LEFT = ("_r", "_right"), ("_l", "_left")
"""How the bodies name their right and left feet."""
GAP_HORIZON_M = 0.2
"""m; leg geoms farther apart than this are not measured further (the gap reads this)."""


@dataclass
class GaitTrace:
    """One episode's steps, as :func:`gait_quality` reads them.

    Attributes:
        dt: s between samples (the control period).
        joints: the dof names, in the order of ``angles``' columns.
        feet: the foot names, in the order of ``forces``' and ``heights``' columns.
        angles: [T, n_dofs] joint angles, rad.
        forces: [T, n_feet] normal ground force per foot, in body weights.
        heights: [T, n_feet] each foot's point above the ground's level, m.
        forward: [T] the pelvis's forward position, m.
    """

    dt: float
    joints: list[str]
    feet: list[str]
    angles: list[np.ndarray] = field(default_factory=list)
    forces: list[np.ndarray] = field(default_factory=list)
    heights: list[np.ndarray] = field(default_factory=list)
    forward: list[float] = field(default_factory=list)
    leg_gaps: list[float] = field(default_factory=list)
    """[T] the smallest signed distance between the legs' contact geoms (m), where measured"""

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``angles``, ``forces``, ``heights`` and ``forward`` as arrays."""
        return (
            np.array(self.angles, dtype=float).reshape(-1, len(self.joints)),
            np.array(self.forces, dtype=float).reshape(-1, len(self.feet)),
            np.array(self.heights, dtype=float).reshape(-1, len(self.feet)),
            np.array(self.forward, dtype=float),
        )


class GaitRecorder(Observer):
    """Records a :class:`GaitTrace` of the episode it watches (its state after the reset and
    after every step), in :attr:`trace`."""

    def __init__(self) -> None:
        self.trace: GaitTrace | None = None
        self._leg_pairs: list[tuple[int, int]] = []

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        sim = env.sim
        self.trace = GaitTrace(env.dt, list(sim.dof_names), list(sim.foot_names))
        self._weight_n = GRAVITY * sim.report.mass
        self._leg_pairs = leg_geom_pairs(sim.model) if env.backend == "mujoco" else []
        self._sample(env)

    def on_step(
        self,
        env: MuscleEnv,
        action: np.ndarray,
        obs: np.ndarray,
        reward: float,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> None:
        if info.get("health", "ok") == "ok":
            self._sample(env)

    def _sample(self, env: MuscleEnv) -> None:
        assert self.trace is not None
        sim = env.sim
        state = sim.state()
        feet = sim.foot_positions()
        self.trace.angles.append(np.array(state.dof_pos, dtype=float))
        self.trace.forces.append(np.asarray(state.foot_forces, dtype=float) / self._weight_n)
        self.trace.heights.append(np.array([feet[f][sim.up_axis] for f in self.trace.feet]))
        self.trace.forward.append(float(state.pelvis_pos[sim.forward_axis]))
        if self._leg_pairs:
            self.trace.leg_gaps.append(smallest_gap(sim.model, sim.data, self._leg_pairs))


@dataclass(frozen=True)
class GaitQuality:
    """:func:`gait_quality`'s figures (NaN where fewer than one whole stride was walked)."""

    strides: int
    """whole strides, right heel strike to right heel strike"""
    stride_length_m: float
    stride_time_s: float
    cadence_steps_per_min: float
    step_time_asymmetry: float
    """``|right-to-left - left-to-right| / their mean`` step time; 0 is symmetric"""
    clearance_m: dict[str, float]
    """foot -> the mean highest point of its swings above its height in stance"""
    joint_rms_rad: dict[str, float]
    """joint -> RMS of the mean cycle against the recording, over the cycle"""
    cycle: dict[str, list[float]]
    """joint -> the mean angle (rad) at each of the recording's sample points"""
    cycle_sd: dict[str, list[float]]
    """joint -> the standard deviation over the strides at each sample point"""
    reference: dict[str, list[float]]
    """joint -> the recording's angle at each sample point"""
    leg_gap_min_m: float | None = None
    """the closest the legs' contact geoms came, m (below 0: through each other); None where
    not measured"""
    interpenetrating_fraction: float | None = None
    """the share of steps where a pair of the legs' geoms interpenetrated"""

    def summary(self) -> dict[str, float]:
        """The scalar figures (no curves), for a table."""
        rms = [v for v in self.joint_rms_rad.values() if math.isfinite(v)]
        return {
            "strides": float(self.strides),
            "stride_length_m": self.stride_length_m,
            "stride_time_s": self.stride_time_s,
            "cadence_steps_per_min": self.cadence_steps_per_min,
            "step_time_asymmetry": self.step_time_asymmetry,
            "joint_rms_rad_mean": float(np.mean(rms)) if rms else math.nan,
        }


def in_stance(forces: np.ndarray, dt: float) -> np.ndarray:
    """[T, n_feet] bool from ground forces [T, n_feet] (body weights) sampled every ``dt`` s:
    at least ``CONTACT_FRACTION``, and gaps shorter than ``MIN_SWING_S`` filled."""
    stance = np.asarray(forces) >= CONTACT_FRACTION
    for k in range(stance.shape[1]):
        for start, end in _runs(~stance[:, k]):
            if (end - start) * dt < MIN_SWING_S:
                stance[start:end, k] = True
    return stance


def heel_strikes(stance: np.ndarray) -> np.ndarray:
    """Indices at which ``stance`` ([T] bool) turns True: the samples of heel strikes."""
    stance = np.asarray(stance, dtype=bool)
    return np.flatnonzero(stance[1:] & ~stance[:-1]) + 1


def gait_quality(trace: GaitTrace, motion: Motion) -> GaitQuality:
    """The gait of ``trace`` beside ``motion`` (its cycle starts at the right heel strike);
    the joints compared are those both have, the feet those named right and left
    (:data:`RIGHT`, :data:`LEFT`)."""
    angles, forces, heights, forward = trace.arrays()
    stance = in_stance(forces, trace.dt)
    legs = _legs(trace.leg_gaps)
    right, left = _side_index(trace.feet, RIGHT), _side_index(trace.feet, LEFT)
    points = np.arange(motion.samples) / motion.samples
    joints = [j for j in motion.joints if j in trace.joints]
    reference = {j: [motion.at(p).joints[j] for p in points] for j in joints}
    strikes = heel_strikes(stance[:, right]) if right is not None else np.array([], int)
    strides = [(int(a), int(b)) for a, b in itertools.pairwise(strikes)]
    nan = math.nan
    if not strides:
        clearance = _clearance(trace.feet, stance, heights)
        rms = dict.fromkeys(joints, nan)
        return GaitQuality(0, nan, nan, nan, nan, clearance, rms, {}, {}, reference, *legs)
    curves = {}
    for joint in joints:
        column = angles[:, trace.joints.index(joint)]
        curves[joint] = np.array([_resampled(column[a : b + 1], points) for a, b in strides])
    cycle = {j: c.mean(axis=0) for j, c in curves.items()}
    rms = {j: float(np.sqrt(np.mean((cycle[j] - np.array(reference[j])) ** 2))) for j in joints}
    lengths = [forward[b] - forward[a] for a, b in strides]
    times = [(b - a) * trace.dt for a, b in strides]
    stride_time = float(np.mean(times))
    return GaitQuality(
        strides=len(strides),
        stride_length_m=float(np.mean(lengths)),
        stride_time_s=stride_time,
        cadence_steps_per_min=120.0 / stride_time,
        step_time_asymmetry=_step_asymmetry(strides, stance, left, trace.dt),
        clearance_m=_clearance(trace.feet, stance, heights),
        joint_rms_rad=rms,
        cycle={j: c.tolist() for j, c in cycle.items()},
        cycle_sd={j: c.std(axis=0).tolist() for j, c in curves.items()},
        reference=reference,
        leg_gap_min_m=legs[0],
        interpenetrating_fraction=legs[1],
    )


def plot_gait(quality: GaitQuality, path: Path, title: str) -> Path:
    """One panel per joint: the mean angle over the gait cycle (deg) with a band of one
    standard deviation, and the recording; written as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    joints = list(quality.cycle) or list(quality.reference)
    columns = min(3, max(1, len(joints)))
    rows = max(1, math.ceil(len(joints) / columns))
    fig, axes = plt.subplots(rows, columns, figsize=(4 * columns, 2.8 * rows), squeeze=False)
    for ax, joint in zip(axes.flat, joints, strict=False):
        reference = np.degrees(quality.reference[joint])
        cycle_pct = 100.0 * np.arange(len(reference)) / len(reference)
        ax.plot(cycle_pct, reference, color="tab:green", label="recorded")
        if joint in quality.cycle:
            mean, sd = np.degrees(quality.cycle[joint]), np.degrees(quality.cycle_sd[joint])
            ax.plot(cycle_pct, mean, color="tab:blue", label="policy")
            ax.fill_between(cycle_pct, mean - sd, mean + sd, color="tab:blue", alpha=0.25)
            ax.set_title(f"{joint} (RMS {np.degrees(quality.joint_rms_rad[joint]):.1f} deg)")
        else:
            ax.set_title(joint)
        ax.set_xlabel("% gait cycle")
        ax.set_ylabel("deg")
    for ax in list(axes.flat)[len(joints) :]:
        ax.axis("off")
    axes.flat[0].legend(loc="best", fontsize="small")
    fig.suptitle(
        f"{title}: {quality.strides} strides, {quality.stride_length_m:.2f} m, "
        f"{quality.cadence_steps_per_min:.0f} steps/min, step asymmetry "
        f"{quality.step_time_asymmetry:.2f}"
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def leg_geom_pairs(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """Geom id pairs of MyoSuite's leg-on-leg contacts (``leg_contact_pairs``) that
    ``model`` has (none on a body without those geoms)."""
    names = {model.geom(i).name: i for i in range(model.ngeom)}
    return [(names[a], names[b]) for a, b, _ in leg_contact_pairs() if a in names and b in names]


def smallest_gap(model: mujoco.MjModel, data: mujoco.MjData, pairs: list[tuple[int, int]]) -> float:
    """The smallest signed distance (m) between the geoms of ``pairs`` in ``data``'s pose
    (negative: penetration depth); pairs more than ``GAP_HORIZON_M`` apart count as that."""
    fromto = np.zeros(6)
    return min(
        float(mujoco.mj_geomDistance(model, data, a, b, GAP_HORIZON_M, fromto)) for a, b in pairs
    )


def _legs(gaps: list[float]) -> tuple[float | None, float | None]:
    """(closest, share of steps below 0) of a trace's leg gaps; (None, None) unmeasured."""
    if not gaps:
        return None, None
    values = np.asarray(gaps)
    return float(values.min()), float(np.mean(values < 0.0))


def _side_index(feet: list[str], suffixes: tuple[str, ...]) -> int | None:
    """Index of the first foot named with one of ``suffixes`` (:data:`RIGHT`, :data:`LEFT`),
    or None."""
    return next((i for i, f in enumerate(feet) if f.endswith(suffixes)), None)


def _resampled(values: np.ndarray, points: np.ndarray) -> np.ndarray:
    """[n + 1] samples of one stride (both heel strikes included) at ``points`` in [0, 1)."""
    at = np.linspace(0.0, 1.0, len(values))
    return np.interp(points, at, values)


def _step_asymmetry(
    strides: list[tuple[int, int]], stance: np.ndarray, left: int | None, dt: float
) -> float:
    """``|right-to-left - left-to-right| / mean`` step time over the strides with one left
    heel strike inside (NaN without one)."""
    if left is None:
        return math.nan
    left_strikes = heel_strikes(stance[:, left])
    first, second = [], []
    for a, b in strides:
        inside = left_strikes[(left_strikes > a) & (left_strikes < b)]
        if len(inside) == 1:
            first.append((inside[0] - a) * dt)
            second.append((b - inside[0]) * dt)
    if not first:
        return math.nan
    r_to_l, l_to_r = float(np.mean(first)), float(np.mean(second))
    return abs(r_to_l - l_to_r) / (0.5 * (r_to_l + l_to_r))


def _clearance(feet: list[str], stance: np.ndarray, heights: np.ndarray) -> dict[str, float]:
    """Per foot, the mean over its swings of the highest point above its median stance
    height (NaN for a foot that never swings, or never stands)."""
    out = {}
    for k, foot in enumerate(feet):
        on_ground = stance[:, k]
        if on_ground.all() or not on_ground.any():
            out[foot] = math.nan
            continue
        ground = float(np.median(heights[on_ground, k]))
        peaks = [float(heights[a:b, k].max()) - ground for a, b in _runs(~on_ground)]
        out[foot] = float(np.mean(peaks)) if peaks else math.nan
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each run of True in ``mask`` that starts and ends inside it."""
    edges = np.flatnonzero(np.diff(mask.astype(int)))
    starts = [e + 1 for e in edges if mask[e + 1]]
    ends = [e + 1 for e in edges if not mask[e + 1]]
    return [(s, next(e for e in ends if e > s)) for s in starts if any(e > s for e in ends)]
