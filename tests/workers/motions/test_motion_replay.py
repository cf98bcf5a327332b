"""Kinematic replay of every shipped motion on its body's MuJoCo model (``mj_kinematics``).

Over the whole cycle (4 points per sample, so the interpolation is replayed too), the pelvis
moving forward at the motion's forward speed:

- no contact geom of a foot goes below the floor by more than :data:`FLOOR_MARGIN_M`
  (measured worst: 0.6 cm, MyoLeg walk; 0.1 cm for the others);
- a foot in stance is on the floor: its lowest point within :data:`STANCE_HEIGHT_M` (measured
  worst 4.2 cm, the gait2d walk at heel strike, where the force plate already reads a
  contact; 0.6 cm for the others);
- a foot in stance stands nearly still in the world: the median horizontal speed of its
  contact centroid below :data:`STILL_MEDIAN_M_S` (measured 0.02 to 0.26 m/s), and 90 % of
  the stance samples' speed of its grounded contact geom (heel, then toe as it rolls over)
  below :data:`STILL_P90_M_S` (measured 0.17 to 0.65 m/s, highest for MyoLeg's walk, whose
  foot pivots on a toe that cannot bend). For scale: the feet swing at 3 to 8 m/s.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from gaitforge.workers.motions import load_motion
from gaitforge.workers.sim.mujoco.motion_replay import Replay

FLOOR_MARGIN_M = 0.02
STANCE_HEIGHT_M = 0.05
STILL_MEDIAN_M_S = 0.3
STILL_P90_M_S = 0.8
SHIPPED = [
    ("gait2d", "walk"),
    ("gait2d", "run"),
    ("myoleg", "walk"),
    ("myoleg", "run"),
    ("gait2354", "walk"),
    ("gait14dof22musc", "walk"),
]


@cache
def _replay(body: str) -> Replay:
    return Replay(body)


@cache
def _trace(body: str, name: str) -> dict[str, np.ndarray]:
    """Per foot over one cycle: lowest point (m), centroid x, grounded geom x (m, world), stance;
    and ``dt`` (s)."""
    motion = load_motion(body, name)
    replay = _replay(body)
    k_total = 4 * motion.samples
    dt = motion.period_s / k_total
    x = 0.0
    keys = [k for f in motion.feet for k in (f, f"{f}:cx", f"{f}:gx", f"{f}:st")]
    out: dict[str, list] = {k: [] for k in keys}
    for k in range(k_total):
        state = motion.at(k / k_total)
        replay.pose(
            state.joints,
            state.pelvis_pitch,
            state.pelvis_height,
            x=x,
            list_=state.pelvis_list,
            rotation=state.pelvis_rotation,
        )
        assert replay.pelvis_origin()[replay.up] == pytest.approx(state.pelvis_height)
        for foot in motion.feet:
            out[foot].append(replay.lowest(foot))
            out[f"{foot}:cx"].append(replay.centroid(foot)[0])
            out[f"{foot}:gx"].append(replay.lowest_geom_centre(foot)[0])
            out[f"{foot}:st"].append(state.stance[foot])
        x += state.forward_speed * dt
    return {k: np.asarray(v) for k, v in out.items()} | {"dt": np.asarray(dt)}


def _speed(x: np.ndarray, dt: float) -> np.ndarray:
    """|dx/dt| by central differences (the ends dropped: no wrap, x grows with the pelvis)."""
    return np.abs(x[2:] - x[:-2]) / (2 * dt)


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_feet_stay_above_the_floor(body: str, name: str) -> None:
    trace = _trace(body, name)
    for foot in load_motion(body, name).feet:
        assert trace[foot].min() > -FLOOR_MARGIN_M, (foot, trace[foot].min())
        stance = trace[f"{foot}:st"]
        assert trace[foot][stance].max() < STANCE_HEIGHT_M, (foot, trace[foot][stance].max())
        # in swing the foot lifts clear of the floor at some point
        assert trace[foot][~stance].max() > 0.03


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_stance_feet_stand_still(body: str, name: str) -> None:
    trace = _trace(body, name)
    dt = float(trace["dt"])
    for foot in load_motion(body, name).feet:
        stance = trace[f"{foot}:st"][1:-1]
        centroid = _speed(trace[f"{foot}:cx"], dt)
        grounded = _speed(trace[f"{foot}:gx"], dt)
        assert np.median(centroid[stance]) < STILL_MEDIAN_M_S, (foot, np.median(centroid[stance]))
        assert np.percentile(grounded[stance], 90) < STILL_P90_M_S
        # the swing foot, by contrast, overtakes the body
        assert centroid[~stance].max() > 2 * load_motion(body, name).speed_m_s
