"""Gait quality beside a recorded gait (``learner.evaluation.gait_quality``): the recording
judged against itself on fixed data (its strides, cadence, symmetry and clearance known),
bounces at touchdown ignored, MyoLeg's legs through each other measured in real poses, and
the shipped walker's first episode through ``gaitforge evaluate --gait`` (real MuJoCo),
judged by bounds."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from gaitforge.learner.evaluation.evaluate import compared_motion
from gaitforge.learner.evaluation.gait_quality import (
    GaitTrace,
    gait_quality,
    leg_geom_pairs,
    plot_gait,
    smallest_gap,
)
from gaitforge.learner.evaluation.observers import EvaluationError
from gaitforge.service.cli import app
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.motions import load_motion
from gaitforge.workers.scenes import load_scene
from typer.testing import CliRunner

WALKER = Path(__file__).resolve().parents[2] / "examples" / "policies" / "walk-2d"
CYCLES = 5
SWING_HEIGHT_M = 0.08


def recorded_trace(dropout_at: int | None = None) -> GaitTrace:
    """The recorded planar walk played for ``CYCLES`` strides, one sample per recorded sample,
    each foot loaded with one body weight in stance and lifted ``SWING_HEIGHT_M`` at the top
    of a sine over its swing; ``dropout_at``: the right foot unloaded for that one sample."""
    motion = load_motion("gait2d", "walk")
    n = motion.samples
    trace = GaitTrace(motion.period_s / n, motion.joints, list(motion.feet))
    for i in range(CYCLES * n + 1):
        state = motion.at((i % n) / n)
        trace.angles.append(np.array([state.joints[j] for j in motion.joints]))
        stance = [motion.stance[f][i % n] for f in motion.feet]
        forces = np.array([1.0 if down else 0.0 for down in stance])
        if dropout_at == i:
            forces[motion.feet.index("foot_right")] = 0.0
        trace.forces.append(forces)
        heights = [_swing_height(motion.stance[f], i % n) for f in motion.feet]
        trace.heights.append(np.array(heights))
        trace.forward.append(motion.speed_m_s * i * trace.dt)
    return trace


def _swing_height(stance: list[bool], k: int) -> float:
    """0 in stance; over a swing, ``SWING_HEIGHT_M`` times a sine from lift-off to touchdown."""
    if stance[k]:
        return 0.0
    n = len(stance)
    start = next(j for j in range(k, k - n, -1) if stance[j % n]) + 1
    end = next(j for j in range(k, k + n) if stance[j % n])
    return SWING_HEIGHT_M * math.sin(math.pi * (k - start + 0.5) / (end - start))


def test_the_recording_judged_against_itself() -> None:
    motion = load_motion("gait2d", "walk")
    quality = gait_quality(recorded_trace(), motion)
    assert quality.strides == CYCLES - 1  # right heel strikes at the start of cycles 2..5
    assert quality.stride_time_s == pytest.approx(motion.period_s)
    assert quality.stride_length_m == pytest.approx(motion.speed_m_s * motion.period_s)
    assert quality.cadence_steps_per_min == pytest.approx(120.0 / motion.period_s)
    assert max(quality.joint_rms_rad.values()) < 1e-9
    # the left heel strikes 31 of 60 samples after the right: (31 - 29) / 30
    assert quality.step_time_asymmetry == pytest.approx(2 / 30)
    for foot, clearance in quality.clearance_m.items():
        assert SWING_HEIGHT_M * 0.98 < clearance <= SWING_HEIGHT_M, foot


def test_a_bounce_at_touchdown_is_not_a_heel_strike() -> None:
    motion = load_motion("gait2d", "walk")
    bounced = gait_quality(recorded_trace(dropout_at=2 * motion.samples + 3), motion)
    assert bounced.strides == CYCLES - 1
    assert bounced.stride_time_s == pytest.approx(motion.period_s)


def test_standing_still_has_no_stride_and_still_plots(tmp_path: Path) -> None:
    motion = load_motion("gait2d", "walk")
    trace = GaitTrace(0.04, motion.joints, list(motion.feet))
    for _ in range(50):
        trace.angles.append(np.zeros(len(motion.joints)))
        trace.forces.append(np.ones(2))
        trace.heights.append(np.zeros(2))
        trace.forward.append(0.0)
    quality = gait_quality(trace, motion)
    assert quality.strides == 0 and math.isnan(quality.cadence_steps_per_min)
    assert plot_gait(quality, tmp_path / "still.png", "standing").stat().st_size > 0


def test_the_gait_is_compared_with_the_clocks_motion_or_the_bodys_walk() -> None:
    assert compared_motion(load_scene("run-2d+clock")).name == "run"
    assert compared_motion(load_scene("walk-2d")).name == "walk"
    with pytest.raises(EvaluationError, match=r"gait: scene 'elbow-reach' has no gait clock"):
        compared_motion(load_scene("elbow-reach"))


def test_the_shipped_walkers_gait_is_reported_and_plotted(tmp_path: Path) -> None:
    """Bounds with margin, not the episode's figures: a planar walk at 1.2-1.4 m/s."""
    plot, out = tmp_path / "gait.png", tmp_path / "report.json"
    args = ["evaluate", str(WALKER), "--episodes", "1", "--gait", str(plot), "--json-out", str(out)]
    result = CliRunner().invoke(app, args, env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert "gait (first episode):" in result.output and plot.stat().st_size > 10_000
    gait = json.loads(out.read_text())["gait"]
    assert set(gait["reference"]) == set(load_motion("gait2d", "walk").joints)
    if gait["strides"]:  # an episode that falls at once walks no whole stride
        assert 60 < gait["cadence_steps_per_min"] < 200
        assert 0.3 < gait["stride_length_m"] < 3.0
        assert all(0 <= rms < 1.0 for rms in gait["joint_rms_rad"].values())


def test_myolegs_legs_through_each_other_read_below_zero() -> None:
    """MyoLeg standing keeps its thighs about 2.5 cm apart; both hips adducted 0.6 rad put
    them through each other (real MuJoCo; the scene's own contacts play no part). A planar
    body has no such geoms."""
    env = MuscleEnv("walk-3d")
    env.reset(seed=0)
    m, d = env.sim.model, env.sim.data
    pairs = leg_geom_pairs(m)
    assert len(pairs) == 26
    assert 0.0 < smallest_gap(m, d, pairs) < 0.1
    for side in ("r", "l"):
        d.qpos[m.jnt_qposadr[m.joint(f"hip_adduction_{side}").id]] = 0.6
    mujoco.mj_forward(m, d)
    assert smallest_gap(m, d, pairs) < 0.0
    assert leg_geom_pairs(MuscleEnv("walk-2d").sim.model) == []


def test_the_legs_figures_read_the_trace() -> None:
    motion = load_motion("gait2d", "walk")
    trace = recorded_trace()
    trace.leg_gaps = [0.03] * (len(trace.forward) - 4) + [-0.01, -0.002, 0.01, 0.02]
    quality = gait_quality(trace, motion)
    assert quality.leg_gap_min_m == -0.01
    assert quality.interpenetrating_fraction == pytest.approx(2 / len(trace.forward))
    assert gait_quality(recorded_trace(), motion).leg_gap_min_m is None
