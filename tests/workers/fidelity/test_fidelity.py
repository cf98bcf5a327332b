"""Fidelity sweeps and stress on the real simulators (small grids, short runs)."""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.fidelity.held import held_rollout, rms_error, with_profile
from gaitforge.workers.fidelity.reference import MARGIN, converged_reference
from gaitforge.workers.fidelity.stress import SCENARIOS, bisect_limits, run_scenario
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim import make_simulator

EULER_20MS = FidelityProfile(integrator="euler", timestep=0.02)
IMPLICITFAST_2MS = FidelityProfile(integrator="implicitfast", timestep=0.002)


def test_mujoco_reference_is_converged_by_the_margin() -> None:
    scene = load_scene("walk-2d")
    ref = converged_reference(scene, "mujoco", tolerance=0.01, seconds=0.5)
    assert ref.rollout.health == "ok" and ref.rollout.steps == 50
    assert 0 < ref.refined_change < 0.01 / MARGIN, ref.refined_change
    assert ref.margin >= MARGIN and ref.converged
    # a coarse setting is measurably off the reference, so the error is not trivially 0
    coarse = held_rollout(scene, "mujoco", FidelityProfile(integrator="euler", timestep=0.005), 0.5)
    assert rms_error(coarse, ref.rollout, 0.5, 0.01) > ref.refined_change * MARGIN


def test_reference_not_converged_is_reported() -> None:
    """Judged against a tolerance far below its own refinement change, the same reference
    is reported as not converged."""
    ref = converged_reference(load_scene("walk-2d"), "mujoco", tolerance=1e-7, seconds=0.2)
    assert not ref.converged and ref.margin < MARGIN


def test_held_variant_holds_the_pelvis_off_the_ground() -> None:
    scene = load_scene("walk-2d")
    for backend, seconds in (("mujoco", 0.5), ("opensim", 0.1)):
        profile = scene.profile(backend)
        run = held_rollout(scene, backend, profile, seconds)
        assert run.health == "ok", backend
        assert run.root_drift < 1e-4, (backend, run.root_drift)
        assert np.ptp(run.q, axis=0).max() > 0.01, backend  # the legs do move
    sim = make_simulator(with_profile(scene, "mujoco", scene.profile("mujoco")), "mujoco")
    sim.reset(0)
    from gaitforge.workers.fidelity.held import hold

    hold(sim, "mujoco")
    assert sim.state().foot_forces.sum() == 0.0


def test_myoleg_euler_20ms_full_excitation_resets_silently_and_is_flagged() -> None:
    scene = with_profile(load_scene("walk-3d"), "mujoco", EULER_20MS)
    sim = make_simulator(scene, "mujoco")
    sim.reset(0)
    m, d = sim.model, sim.data
    d.ctrl[:] = 1.0
    badqacc = mujoco.mjtWarning.mjWARN_BADQACC
    for _ in range(50):  # raw MuJoCo: the blow-up ends in a silent reset
        t = d.time
        mujoco.mj_step(m, d)
        if d.warning[badqacc].number:
            break
    assert d.warning[badqacc].number > 0
    assert d.time <= t and np.isfinite(d.qvel).all()  # time went back; the state looks fine
    assert run_scenario(load_scene("walk-3d"), "mujoco", EULER_20MS, "ones", 0.5) != "ok"


def test_stable_setting_is_not_flagged() -> None:
    scene = load_scene("walk-3d")
    for scenario in ("ones", "random", "drop"):
        assert run_scenario(scene, "mujoco", IMPLICITFAST_2MS, scenario, 0.5) == "ok"


def test_bisection_brackets_the_largest_stable_step() -> None:
    scene = load_scene("walk-3d")
    (limit,) = bisect_limits(scene, "mujoco", 0.3, ("euler",), ("ones",))
    assert limit.largest_stable is not None and limit.smallest_unstable is not None
    assert limit.largest_stable < limit.smallest_unstable <= 0.02
    stable = FidelityProfile(integrator="euler", timestep=limit.largest_stable)
    unstable = FidelityProfile(integrator="euler", timestep=limit.smallest_unstable)
    assert run_scenario(scene, "mujoco", stable, "ones", 0.3) == "ok"
    assert run_scenario(scene, "mujoco", unstable, "ones", 0.3) != "ok"


def test_every_stress_scenario_runs_healthy_at_the_default_profile() -> None:
    """All six scenarios on walk-2d at MuJoCo's default profile stay healthy."""
    scene = load_scene("walk-2d")
    for scenario in SCENARIOS:
        assert run_scenario(scene, "mujoco", scene.profile("mujoco"), scenario, 0.2) == "ok"


def test_pruning_check_measures_the_error_pruning_introduces() -> None:
    """walk-3d welds the subtalar and toe joints: on the held variant the unpruned body
    moves them, so the kept joints' trajectories differ by a small, non-zero amount."""
    from gaitforge.workers.fidelity.grid import SweepSize
    from gaitforge.workers.fidelity.model_error import pruning
    from gaitforge.workers.fidelity.reference import REFERENCE

    scene = load_scene("walk-3d")
    size = SweepSize(short=0.1, long=0.2, seeds=1, task_s=0.2, repeats=1)
    reference = held_rollout(scene, "mujoco", REFERENCE["mujoco"], size.long)
    diff = pruning(scene, "mujoco", reference, size)
    assert 1e-5 < diff.rms_long < 0.1, diff
    assert diff.speed_ratio > 0 and diff.note.startswith("speed at")
