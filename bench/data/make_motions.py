"""Write the project's reference motions from OpenSim's example gait data (run once).

    python bench/data/make_motions.py /path/to/reference/gait

reads ``subject01_walk_IK.mot`` + ``subject01_walk_grf.mot`` + ``walk_subject_controls.sto``
(treadmill walk), ``subject02_running_ik.mot`` (treadmill run) and ``normal.mot`` (one
normalised 3-D walking cycle) and writes ``workers/motions/data/``: ``gait2d-walk.yaml``,
``gait2d-run.yaml``, ``myoleg-walk.yaml``, ``myoleg-run.yaml``, ``gait2354-walk.yaml`` and
``gait14dof22musc-walk.yaml`` (the 3-D walk on the imported bodies) and
``gait2d-walk-excitations.yaml``. It is a run-once data script, no part of the installed
package; it replays the motions on the MuJoCo models (``workers.sim.mujoco.motion_replay``),
which the motions package itself never imports (it imports bodies only).

Method, per motion (details in each file's ``source`` and the README's "Motion imitation"):

1. One stride, right heel strike to right heel strike: from the vertical ground force where
   there is one (walk), else from the replayed foot height (run); ``normal.mot`` starts at
   heel strike already.
2. Resampled onto N = :data:`SAMPLES` phases; the stride's small end-to-start mismatch removed
   by a linear detrend; then the first :data:`HARMONICS` Fourier harmonics kept, so angles and
   their speeds are continuous across the seam.
3. Replayed on the body (``mj_kinematics``): the pelvis height is the recorded (treadmill)
   pelvis height plus an offset that puts the lower stance foot's lowest contact point on the
   floor at each sample (interpolated across flight phases), or, with no pelvis height in the
   data, set per sample so that the lower foot touches; the feet's centroids relative to the
   pelvis come from the same poses. Stance: force plates (walk), else the replay (see
   :func:`kinematic_stance`).
4. The forward speed is the treadmill belt speed seen in the kinematics: the median backward
   speed, relative to the treadmill, of the stance foot's grounded contact geom (so that a
   stance foot stands still in the world when the pelvis moves at the motion's speed); the
   within-cycle fluctuation is the rate of change of the recorded pelvis_tx. ``normal.mot``
   has no time: its period is chosen (:data:`NORMAL_PERIOD_S`), its speed follows.
5. The CMC excitations of the walk's stride, averaged over each phase bin.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import yaml
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.motions import data_dir, load_motion_file
from gaitforge.workers.motions.signals import (
    HARMONICS,
    SAMPLES,
    cycle,
    debounce,
    periodic_rate,
    read_mot,
    rising_edges,
)
from gaitforge.workers.sim.mujoco.motion_replay import Replay

log = logging.getLogger(__name__)

GRF_THRESHOLD_N = 20.0
"""Vertical ground force above which a foot is in stance (the force plates' noise is ~5 N)."""
CONTACT_HEIGHT_M = 0.05
"""With no force data, a stance foot's lowest point is within this of the floor level."""
BELT_SHARE = 0.8
"""With no force data, a stance foot moves backward (relative to the treadmill) faster than
this share of the belt speed."""
WALK_2D_JOINTS = [f"{j}_{s}" for s in "rl" for j in ("hip_flexion", "knee_angle", "ankle_angle")]
WALK_3D_JOINTS = [
    f"{j}_{s}"
    for s in "rl"
    for j in ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle")
]
FEET = ["foot_right", "foot_left"]
HEADER = "# Written by python bench/data/make_motions.py; do not edit.\n"


def replay_feet(
    replay: Replay,
    joints: dict[str, np.ndarray],
    pitch: np.ndarray,
    height: np.ndarray,
    list_: np.ndarray | None = None,
    rotation: np.ndarray | None = None,
) -> tuple[dict, dict]:
    """Per foot: lowest point height [n] (m) and centroid minus pelvis origin [n, 3] (m); also
    (key ``<foot>:low``) the lowest geom's centre minus pelvis origin [n, 3] (m)."""
    n = len(pitch)
    lows = {f: np.zeros(n) for f in FEET}
    rel = {k: np.zeros((n, 3)) for f in FEET for k in (f, f"{f}:low")}
    for k in range(n):
        replay.pose(
            {j: float(v[k]) for j, v in joints.items()},
            float(pitch[k]),
            float(height[k]),
            list_=0.0 if list_ is None else float(list_[k]),
            rotation=0.0 if rotation is None else float(rotation[k]),
        )
        origin = replay.pelvis_origin()
        for f in FEET:
            lows[f][k] = replay.lowest(f)
            rel[f][k] = replay.centroid(f) - origin
            rel[f"{f}:low"][k] = replay.lowest_geom_centre(f) - origin
    return lows, rel


def belt_speed(
    rel: dict[str, np.ndarray], stance: dict[str, np.ndarray], tx_rate: np.ndarray, period: float
) -> float:
    """Median backward speed (m/s), relative to the treadmill, of the stance feet's lowest
    contact geoms (the ones on the ground)."""
    speeds = []
    for f in FEET:
        v = periodic_rate(rel[f"{f}:low"][:, 0], period) + tx_rate
        speeds.extend(-v[stance[f]])
    return float(np.median(speeds))


def _series(x: np.ndarray, digits: int = 4) -> list[float]:
    return [round(float(v), digits) for v in x]


def write_motion(
    path: Path,
    *,
    name: str,
    body: str,
    period: float,
    speed: float,
    source: str,
    joints: dict[str, np.ndarray],
    pelvis: dict[str, np.ndarray],
    speed_offset: np.ndarray,
    rel: dict[str, np.ndarray],
    stance: dict[str, np.ndarray],
) -> None:
    """Write one motion file and check it loads."""
    data = {
        "name": name,
        "body": body,
        "period_s": round(period, 4),
        "speed_m_s": round(speed, 3),
        "source": " ".join(source.split()),
        "feet": FEET,
        "joint_angles": {j: _series(v) for j, v in joints.items()},
        **{k: _series(v) for k, v in pelvis.items()},
        "forward_speed_offset": _series(speed_offset, 3),
        "feet_rel_pelvis": {f: [_series(p) for p in rel[f]] for f in FEET},  # centroids
        "stance": {f: [bool(s) for s in stance[f]] for f in FEET},
    }
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    path.write_text(HEADER + text)
    load_motion_file(path, body)
    log.info("wrote %s: period %.3f s, speed %.2f m/s", path, period, speed)


def contact_height(
    replay: Replay,
    joints: dict[str, np.ndarray],
    pitch: np.ndarray,
    ty: np.ndarray,
    stance: dict[str, np.ndarray],
    **lateral: np.ndarray,
) -> np.ndarray:
    """Pelvis height [n] (m): the recorded ``ty`` plus an offset that puts the lowest stance
    foot's lowest point on the floor; across samples with no foot in stance (flight) the
    offset is interpolated linearly (periodically) between the neighbouring stance samples;
    then smoothed like every series (:func:`cycle`)."""
    lows, _ = replay_feet(replay, joints, pitch, ty, **lateral)
    n = len(ty)
    any_stance = np.zeros(n, bool)
    offset = np.full(n, np.inf)
    for f in FEET:
        offset = np.where(stance[f], np.minimum(offset, lows[f]), offset)
        any_stance |= stance[f]
    k = np.flatnonzero(any_stance)
    filled = np.interp(np.arange(n), k, -offset[k], period=n)
    return cycle(np.arange(n + 1), np.append(ty + filled, ty[0] + filled[0]), 0, n, n)


def kinematic_stance(
    t: np.ndarray, lows: dict[str, np.ndarray], rel: dict[str, np.ndarray], tx: np.ndarray
) -> dict[str, np.ndarray]:
    """Stance per foot with no force data: the foot moves backward with the belt (the centre of
    its lowest contact geom, the one on the ground, relative to the treadmill, faster than
    :data:`BELT_SHARE` of the belt speed, the belt speed being the 5th percentile of all
    feet's backward speeds) and is low (lowest point within :data:`CONTACT_HEIGHT_M` of the
    floor level, the 2nd percentile of both feet's lowest points)."""
    floor = float(np.percentile(np.concatenate(list(lows.values())), 2))
    vx = {f: np.gradient(rel[f"{f}:low"][:, 0] + tx, t) for f in lows}
    belt = -float(np.percentile(np.concatenate(list(vx.values())), 5))
    return {
        f: debounce((vx[f] < -BELT_SHARE * belt) & (lows[f] < floor + CONTACT_HEIGHT_M))
        for f in lows
    }


def build(
    replay: Replay,
    *,
    name: str,
    period: float,
    joints: dict[str, np.ndarray],
    pitch: np.ndarray,
    ty: np.ndarray,
    tx: np.ndarray | None,
    stance: dict[str, np.ndarray],
    source: str,
    speed: float | None = None,
    **lateral: np.ndarray,
) -> None:
    """Pelvis height, feet and speed by replay; write ``data/<body>-<name>.yaml``."""
    height = contact_height(replay, joints, pitch, ty, stance, **lateral)
    lows, rel = replay_feet(replay, joints, pitch, height, **lateral)
    tx_rate = np.zeros(len(ty)) if tx is None else periodic_rate(tx, period)
    belt = belt_speed(rel, stance, tx_rate, period)
    log.info(
        "%s %s: belt speed from the kinematics %.3f m/s; lowest foot point %.1f cm",
        replay.body,
        name,
        belt,
        100 * min(v.min() for v in lows.values()),
    )
    pelvis = {"pelvis_height": height, "pelvis_pitch": pitch}
    if lateral:
        pelvis |= {"pelvis_list": lateral["list_"], "pelvis_rotation": lateral["rotation"]}
    write_motion(
        data_dir() / f"{replay.body}-{name}.yaml",
        name=name,
        body=replay.body,
        period=period,
        speed=belt if speed is None else speed,
        source=source,
        joints=joints,
        pelvis=pelvis,
        speed_offset=tx_rate,
        rel=rel,
        stance=stance,
    )


def walk_2d(ref: Path) -> tuple[float, float]:
    """gait2d walk from subject01 (IK + GRF); returns the stride (t0, t1) in s."""
    ik = read_mot(ref / "subject01_walk_IK.mot")
    grf = read_mot(ref / "subject01_walk_grf.mot")
    forces = {"foot_right": grf["ground_force_vy"], "foot_left": grf["1_ground_force_vy"]}
    strikes = rising_edges(grf["time"], forces["foot_right"] > GRF_THRESHOLD_N)
    t0, t1 = strikes[0], strikes[1]
    period = t1 - t0
    log.info("walk: right heel strikes at %s s (vertical GRF > %g N)", strikes, GRF_THRESHOLD_N)
    t, grid = ik["time"], t0 + period * np.arange(SAMPLES) / SAMPLES
    stance = {f: np.interp(grid, grf["time"], v) > GRF_THRESHOLD_N for f, v in forces.items()}
    joints = {j: cycle(t, np.radians(ik[j]), t0, t1) for j in WALK_2D_JOINTS}
    source = f"""OpenSim example data subject01_walk_IK.mot (treadmill walk, gait10dof18musc
    inverse kinematics, 60 Hz), one stride from right heel strike at {t0:.4f} s to the next at
    {t1:.4f} s, both found where the first force plate's vertical force (right foot,
    subject01_walk_grf.mot) rises above {GRF_THRESHOLD_N:g} N; stance flags from the same
    forces. Angles resampled to {SAMPLES} phases, the stride's end-to-start mismatch removed by
    a linear detrend, {HARMONICS} Fourier harmonics kept. lumbar_extension is not tracked:
    gait2d's scenes lock it at the reference's -0.1396 rad (the IK trunk leans about -26 deg
    against a +10 deg pelvis tilt; the pelvis tilt is kept as recorded). Pelvis height: the
    recorded pelvis_ty plus an offset that puts the lower stance foot's lowest contact sphere
    on the floor in a kinematic replay on gait2d. Forward speed: the treadmill belt speed seen
    in the kinematics, the median backward speed of the stance foot's grounded contact sphere
    relative to the treadmill; the within-stride fluctuation is the
    rate of change of pelvis_tx. The treadmill's own speed is not recorded."""
    build(
        Replay("gait2d"),
        name="walk",
        period=period,
        joints=joints,
        pitch=cycle(t, np.radians(ik["pelvis_tilt"]), t0, t1),
        ty=cycle(t, ik["pelvis_ty"], t0, t1),
        tx=cycle(t, ik["pelvis_tx"], t0, t1),
        stance=stance,
        source=source,
    )
    write_excitations(ref, t0, t1)
    return t0, t1


def write_excitations(ref: Path, t0: float, t1: float) -> None:
    """CMC excitations of the walk's stride, bin-averaged onto the motion's phase grid."""
    sto = read_mot(ref / "walk_subject_controls.sto")
    muscles = topology_for("gait2d").muscles
    period = t1 - t0
    fine = t0 + period * (np.arange(SAMPLES * 20) + 0.5 - 10) / (SAMPLES * 20)  # bins centred
    out = {}
    for m in muscles:
        values = np.interp(fine, sto["time"], sto[m]).reshape(SAMPLES, 20).mean(axis=1)
        out[m] = _series(np.clip(values, 0.0, 1.0), 4)
    data = {
        "body": "gait2d",
        "motion": "walk",
        "source": " ".join(
            f"""OpenSim example data walk_subject_controls.sto: the muscle
            excitations computed muscle control found for the same treadmill walk (with residual
            and reserve actuators), over the motion's stride {t0:.4f} to {t1:.4f} s, averaged
            over each of the {SAMPLES} phase bins (centred on phase k/{SAMPLES}), clipped to
            [0, 1]. Excitations, not activations; a plausible muscle pattern, not one that
            balances the body on its own.""".split()
        ),
        "excitations": out,
    }
    path = data_dir() / "gait2d-walk-excitations.yaml"
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    path.write_text(HEADER + text)
    log.info("wrote %s", path)


def _body_joints(body: str, table: dict[str, np.ndarray], names: list[str]) -> dict:
    """Recorded coordinates (degrees, OpenSim signs) -> rad in the body's signs."""
    out = {}
    for j in names:
        sign = -1.0 if body == "myoleg" and j.startswith("knee_angle") else 1.0
        out[j] = sign * np.radians(table[j])
    return out


def run(ref: Path, body: str) -> None:
    """A run from subject02 (Hamner): one stride between right heel strikes found by replay."""
    ik = read_mot(ref / "subject02_running_ik.mot")
    t = ik["time"]
    names = WALK_2D_JOINTS if body == "gait2d" else WALK_3D_JOINTS
    raw = _body_joints(body, ik, names)
    pitch, ty = np.radians(ik["pelvis_tilt"]), ik["pelvis_ty"]
    lateral = {}
    if body == "myoleg":
        lateral = {
            "list_": np.radians(ik["pelvis_list"]),
            "rotation": np.radians(ik["pelvis_rotation"]),
        }
    replay = Replay(body)
    lows, rel = replay_feet(replay, raw, pitch, ty, **lateral)
    stance_all = kinematic_stance(t, lows, rel, ik["pelvis_tx"])
    strikes = rising_edges(t, stance_all["foot_right"])
    periods = np.diff(strikes)
    middle = len(periods) // 2
    i = middle + int(np.argmin(np.abs(periods[middle - 3 : middle + 3] - np.median(periods)))) - 3
    t0, t1 = strikes[i], strikes[i + 1]
    period = t1 - t0
    log.info(
        "run (%s): %d right heel strikes, median stride %.3f s; stride %.3f-%.3f s",
        body,
        len(strikes),
        float(np.median(periods)),
        t0,
        t1,
    )
    grid = t0 + period * np.arange(SAMPLES) / SAMPLES
    near = np.clip(np.searchsorted(t, grid), 0, len(t) - 1)
    stance = {f: stance_all[f][near] for f in FEET}
    joints = {j: cycle(t, v, t0, t1) for j, v in raw.items()}
    cyc_lateral = {k: cycle(t, v, t0, t1) for k, v in lateral.items()}
    if "rotation" in cyc_lateral:  # heading-aligned: the stride's mean yaw is the heading
        cyc_lateral["rotation"] -= cyc_lateral["rotation"].mean()
    tracked = ", ".join(names)
    source = f"""OpenSim example data subject02_running_ik.mot (treadmill run, Hamner, Seth and
    Delp 2010, full-body inverse kinematics, 60 Hz): one stride from right heel strike at
    {t0:.4f} s to the next at {t1:.4f} s (the stride nearest the trial's median of
    {float(np.median(periods)):.3f} s, mid-trial). No force data: heel strikes and stance
    flags come from a kinematic replay on {body}, a foot being in stance while its lowest
    contact geom moves backward with the belt (relative to the treadmill, faster than
    {BELT_SHARE:g} of the belt speed, the 5th percentile of the feet's backward speeds) and its
    lowest contact point is within {100 * CONTACT_HEIGHT_M:g} cm of the floor level (the 2nd
    percentile of both feet's lowest points over the trial). Tracked: {tracked}
    (subtalar and mtp are locked at 0 in the recorded model; lumbar and arms are not in the
    body). Angles resampled to {SAMPLES} phases, detrended to close, {HARMONICS} Fourier
    harmonics kept. Pelvis height: recorded pelvis_ty plus an offset that puts the lower
    stance foot on the floor, interpolated across the flight phases. Forward speed: the
    treadmill belt speed seen in the kinematics (median backward speed of the stance foot's
    grounded contact geom relative to the treadmill); the paper reports about 4 m/s for this
    subject's fast runs; the within-stride fluctuation is the rate of change of pelvis_tx."""
    if body == "myoleg":
        source += " MyoLeg's knee_angle is the recorded one negated (MyoLeg flexes positive)."
    build(
        replay,
        name="run",
        period=period,
        joints=joints,
        pitch=cycle(t, pitch, t0, t1),
        ty=cycle(t, ty, t0, t1),
        tx=cycle(t, ik["pelvis_tx"], t0, t1),
        stance=stance,
        source=source,
        **cyc_lateral,
    )


WALK_CONTACT_M = 0.01
"""normal.mot on MyoLeg: a stance foot's lowest point is within this of the floor."""
NORMAL_PERIOD_S = 1.1
"""Stride period chosen for normal.mot (normalised, no time): a typical adult stride at the
self-selected walking speed (cadence ~109 steps/min)."""


def walk_3d(ref: Path, body: str = "myoleg") -> None:
    """The 3-D walk from normal.mot on MyoLeg or a 3-D neutral body whose coordinates have
    OpenSim's gait names (an imported one): pelvis height and stance by replay (no force, no
    height)."""
    nm = read_mot(ref / "normal.mot")
    t = nm["time"] * NORMAL_PERIOD_S
    period = NORMAL_PERIOD_S
    joints = {j: cycle(t, v, 0, period) for j, v in _body_joints(body, nm, WALK_3D_JOINTS).items()}
    lateral = {
        k: cycle(t, np.radians(nm[c]), 0, period)
        for k, c in (("list_", "pelvis_list"), ("rotation", "pelvis_rotation"))
    }
    lateral["rotation"] -= lateral["rotation"].mean()
    pitch = cycle(t, np.radians(nm["pelvis_tilt"]), 0, period)
    replay = Replay(body)
    ones = np.ones(SAMPLES)
    lows, _ = replay_feet(replay, joints, pitch, ones, **lateral)
    height = 1.0 - np.minimum(lows["foot_right"], lows["foot_left"])  # the lower foot touches
    lows, rel = replay_feet(replay, joints, pitch, height, **lateral)
    stance = {
        f: debounce((lows[f] < WALK_CONTACT_M) & (periodic_rate(rel[f"{f}:low"][:, 0], period) < 0))
        for f in FEET
    }
    nobody = ~(stance["foot_right"] | stance["foot_left"])
    lower_right = lows["foot_right"] <= lows["foot_left"]
    stance["foot_right"] |= nobody & lower_right
    stance["foot_left"] |= nobody & ~lower_right
    shift = int(np.flatnonzero(stance["foot_right"] & ~np.roll(stance["foot_right"], 1))[0])
    log.info(
        "walk (%s): right foot lands at phase %.3f of normal.mot in the replay",
        body,
        shift / SAMPLES,
    )

    def roll(x: np.ndarray) -> np.ndarray:
        return np.roll(x, -shift, axis=0)

    knee = "knee (negated: MyoLeg flexes positive)" if body == "myoleg" else "knee"
    source = f"""OpenSim example data normal.mot (one normalised 3-D walking cycle, 51 rows, 2 %
    apart, from heel strike), on {body}: hip flexion/adduction/rotation, {knee} and ankle per
    side, pelvis tilt/list/rotation (the rotation's mean, the heading, removed). Period
    chosen: {NORMAL_PERIOD_S:g} s, a typical adult stride at the
    self-selected speed (the file has no time). Resampled to {SAMPLES} phases,
    {HARMONICS} Fourier harmonics kept. Pelvis height by kinematic replay on {body}: set per
    sample so that the lower foot's lowest contact point touches the floor (pelvis_ty in the
    file is a constant). Stance from the replay: the foot's lowest point within
    {100 * WALK_CONTACT_M:g} cm of the floor and its grounded contact geom moving backward
    relative to the pelvis; where neither foot passes (the toe of the foot leaving the ground
    stays within 1 cm of it for a few samples, the mtp being held at 0) the lower foot is
    the stance foot. On {body} the right foot
    lands (replay) at phase {shift / SAMPLES:.3f} of normal.mot (its swing foot comes down
    later than in the recorded model): the cycle is shifted so
    that phase 0 is that landing. Forward speed: stride length on {body} (the stance foot's
    backward travel relative to the pelvis) / period; no within-cycle fluctuation (none
    recorded)."""
    build(
        replay,
        name="walk",
        period=period,
        joints={j: roll(v) for j, v in joints.items()},
        pitch=roll(pitch),
        ty=roll(height),
        tx=None,
        stance={f: roll(v) for f, v in stance.items()},
        source=source,
        **{k: roll(v) for k, v in lateral.items()},
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", type=Path, help="folder of the OpenSim gait data")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    walk_2d(args.reference)
    run(args.reference, "gait2d")
    run(args.reference, "myoleg")
    walk_3d(args.reference)
    walk_3d(args.reference, "gait2354")
    walk_3d(args.reference, "gait14dof22musc")


if __name__ == "__main__":
    main()
