"""Write the project's reference motions from OpenSim's example gait data (run once).

    python -m gaitforge.workers.sim.make_motions /path/to/reference/gait

reads ``subject01_walk_IK.mot`` + ``subject01_walk_grf.mot`` + ``walk_subject_controls.sto``
(treadmill walk), ``subject02_running_ik.mot`` (treadmill run) and ``normal.mot`` (one
normalised 3-D walking cycle) and writes ``workers/motions/data/{gait2d,myoleg}-{walk,run}.yaml``
and ``gait2d-walk-excitations.yaml``. It lives in ``sim`` (not in the motions package) because
it replays the motions on the MuJoCo models; the motions package itself imports bodies only.

Method, per motion (details in each file's ``source`` and the README's "Motion imitation"):

1. One stride, right heel strike to right heel strike: from the vertical ground force where
   there is one (walk), else from the replayed foot height (run); ``normal.mot`` starts at
   heel strike already.
2. Resampled onto N = :data:`SAMPLES` phases; the stride's small end-to-start mismatch removed
   by a linear detrend; then the first :data:`HARMONICS` Fourier harmonics kept, so angles and
   their speeds are continuous across the seam.
3. Replayed on the body (``mj_kinematics``): the pelvis height is the recorded (treadmill)
   pelvis height shifted so that the stance feet's lowest contact points touch the floor (the
   median over stance samples is 0), or, with no pelvis height in the data, set per sample so
   that the lower foot touches; feet centroids relative to the pelvis come from the same pose.
4. The forward speed is the treadmill belt speed seen in the kinematics: the mean backward
   speed, relative to the treadmill, of the stance foot's centroid (so that a stance foot
   stands still in the world when the pelvis moves at the motion's speed); the within-cycle
   fluctuation is the rate of change of the recorded pelvis_tx.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import yaml
from gaitforge.workers.motions import data_dir, load_motion_file
from gaitforge.workers.sim.motion_replay import Replay

log = logging.getLogger(__name__)

SAMPLES = 60
"""Samples per cycle in the written files."""
HARMONICS = 15
"""Fourier harmonics kept per stride (gait kinematics hold >99.9 % of their power below 10)."""
GRF_THRESHOLD_N = 20.0
"""Vertical ground force above which a foot is in stance (the force plates' noise is ~5 N)."""
CONTACT_HEIGHT_M = 0.02
"""With no force data: a foot whose lowest point is within this of the floor is in stance."""
WALK_2D_JOINTS = [f"{j}_{s}" for s in "rl" for j in ("hip_flexion", "knee_angle", "ankle_angle")]
MYOLEG_JOINTS = [
    f"{j}_{s}"
    for s in "rl"
    for j in ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle")
]
FEET = ["foot_right", "foot_left"]


def read_mot(path: Path) -> dict[str, np.ndarray]:
    """An OpenSim .mot/.sto table: column name -> values (as stored; degrees stay degrees)."""
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    names = lines[start + 1].split()
    body = [line for line in lines[start + 2 :] if line.strip()]
    rows = np.array([[float(v) for v in line.split()] for line in body])
    return {name: rows[:, i] for i, name in enumerate(names)}


def rising_edges(t: np.ndarray, flag: np.ndarray) -> list[float]:
    """Times where ``flag`` turns on (off before, on after)."""
    idx = np.flatnonzero(~flag[:-1] & flag[1:]) + 1
    return [float(t[i]) for i in idx]


def cycle(t: np.ndarray, x: np.ndarray, t0: float, t1: float, n: int = SAMPLES) -> np.ndarray:
    """``x(t)`` over one stride [t0, t1) as a closed periodic series [n] (see module doc)."""
    grid = t0 + (t1 - t0) * np.arange(n + 1) / n
    y = np.interp(grid, t, x)
    y = y[:-1] - (y[-1] - y[0]) * np.arange(n) / n
    spec = np.fft.rfft(y)
    spec[HARMONICS + 1 :] = 0
    return np.fft.irfft(spec, n)


def periodic_rate(x: np.ndarray, period: float) -> np.ndarray:
    """d/dt of a periodic series [n] by central differences."""
    dt = period / len(x)
    return (np.roll(x, -1) - np.roll(x, 1)) / (2 * dt)


def replay_feet(replay: Replay, joints: dict[str, np.ndarray], pitch: np.ndarray,
                height: np.ndarray, list_: np.ndarray | None = None,
                rotation: np.ndarray | None = None) -> tuple[dict, dict]:  # fmt: skip
    """Per foot: lowest point height [n] (m) and centroid minus pelvis origin [n, 3] (m)."""
    n = len(pitch)
    lows = {f: np.zeros(n) for f in FEET}
    rel = {f: np.zeros((n, 3)) for f in FEET}
    for k in range(n):
        replay.pose(
            {j: float(v[k]) for j, v in joints.items()}, float(pitch[k]), float(height[k]),
            list_=0.0 if list_ is None else float(list_[k]),
            rotation=0.0 if rotation is None else float(rotation[k]),
        )  # fmt: skip
        origin = replay.pelvis_origin()
        for f in FEET:
            lows[f][k] = replay.lowest(f)
            rel[f][k] = replay.centroid(f) - origin
    return lows, rel


def belt_speed(rel: dict[str, np.ndarray], stance: dict[str, np.ndarray], tx_rate: np.ndarray,
               period: float) -> float:  # fmt: skip
    """Mean backward speed (m/s) of the stance feet's centroids relative to the treadmill."""
    speeds = []
    for f in FEET:
        v = periodic_rate(rel[f][:, 0], period) + tx_rate
        speeds.extend(-v[stance[f]])
    return float(np.median(speeds))


def _series(x: np.ndarray, digits: int = 4) -> list[float]:
    return [round(float(v), digits) for v in x]


def write_motion(path: Path, *, name: str, body: str, period: float, speed: float, source: str,
                 joints: dict[str, np.ndarray], pelvis: dict[str, np.ndarray],
                 speed_offset: np.ndarray, rel: dict[str, np.ndarray],
                 stance: dict[str, np.ndarray]) -> None:  # fmt: skip
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
        "feet_rel_pelvis": {f: [_series(p) for p in rel[f]] for f in FEET},
        "stance": {f: [bool(s) for s in stance[f]] for f in FEET},
    }
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    header = "# Written by python -m gaitforge.workers.sim.make_motions; do not edit.\n"
    path.write_text(header + text)
    load_motion_file(path, body)
    log.info("wrote %s: period %.3f s, speed %.2f m/s", path, period, speed)


def contact_height(replay: Replay, joints: dict[str, np.ndarray], pitch: np.ndarray,
                   ty: np.ndarray, stance: dict[str, np.ndarray], **lateral: np.ndarray
                   ) -> np.ndarray:  # fmt: skip
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


def kinematic_stance(lows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Stance per foot from foot height: lowest point within :data:`CONTACT_HEIGHT_M` of the
    floor level (the 2nd percentile of both feet's lowest points)."""
    floor = float(np.percentile(np.concatenate(list(lows.values())), 2))
    return {f: lows[f] < floor + CONTACT_HEIGHT_M for f in lows}


def build(replay: Replay, *, name: str, period: float, joints: dict[str, np.ndarray],
          pitch: np.ndarray, ty: np.ndarray, tx: np.ndarray | None,
          stance: dict[str, np.ndarray], source: str, speed: float | None = None,
          **lateral: np.ndarray) -> None:  # fmt: skip
    """Pelvis height, feet and speed by replay; write ``data/<body>-<name>.yaml``."""
    height = contact_height(replay, joints, pitch, ty, stance, **lateral)
    lows, rel = replay_feet(replay, joints, pitch, height, **lateral)
    tx_rate = np.zeros(len(ty)) if tx is None else periodic_rate(tx, period)
    belt = belt_speed(rel, stance, tx_rate, period)
    log.info("%s %s: belt speed from the kinematics %.3f m/s; lowest foot point %.1f cm",
             replay.body, name, belt, 100 * min(v.min() for v in lows.values()))  # fmt: skip
    pelvis = {"pelvis_height": height, "pelvis_pitch": pitch}
    if lateral:
        pelvis |= {"pelvis_list": lateral["list_"], "pelvis_rotation": lateral["rotation"]}
    write_motion(
        data_dir() / f"{replay.body}-{name}.yaml", name=name, body=replay.body, period=period,
        speed=belt if speed is None else speed, source=source, joints=joints, pelvis=pelvis,
        speed_offset=tx_rate, rel=rel, stance=stance,
    )  # fmt: skip


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
    in the kinematics, the median backward speed of the stance foot's contact centroid relative
    to the treadmill (stride length / period = the same); the within-stride fluctuation is the
    rate of change of pelvis_tx. The treadmill's own speed is not recorded."""
    build(Replay("gait2d"), name="walk", period=period, joints=joints,
          pitch=cycle(t, np.radians(ik["pelvis_tilt"]), t0, t1),
          ty=cycle(t, ik["pelvis_ty"], t0, t1), tx=cycle(t, ik["pelvis_tx"], t0, t1),
          stance=stance, source=source)  # fmt: skip
    return t0, t1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", type=Path, help="folder of the OpenSim gait data")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    walk_2d(args.reference)


if __name__ == "__main__":
    main()
