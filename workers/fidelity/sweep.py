"""``gaitforge fidelity sweep``: measure every profile of the grid, recommend the fastest
within tolerance, and save it as a named profile.

Per profile: speed (median env steps/s over the task runs, one process), integration error
(RMS joint-angle error against the converged reference on the held variant, over
``short`` and ``long`` windows), task-level statistics against the reference's (distance,
fall rate, peak ground force with 95% intervals), and stability (any health cause in any
run). The recommended profile is the fastest stable one whose error is within the
tolerance in both windows: the long window alone can flatter a profile (on walk-3d, Euler
at 2 ms measured 0.009 rad over 2 s but 0.011 over 0.5 s, while Euler at 1 ms measured
0.014 over 2 s), so the larger of the two is what is judged. With a task tolerance (m),
the mean distance covered must also lie within it of the reference's.
"""

from __future__ import annotations

import logging
import platform
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from gaitforge.workers.fidelity import model_error
from gaitforge.workers.fidelity.grid import SweepSize
from gaitforge.workers.fidelity.held import describe, held_rollout, rms_error
from gaitforge.workers.fidelity.reference import (
    MARGIN,
    REFERENCE,
    Reference,
    converged_reference,
)
from gaitforge.workers.fidelity.task import TaskStats, difference, speed_runs
from gaitforge.workers.scenes import Scene, saved_profiles
from gaitforge.workers.scenes.profiles import NAMED_PROFILES, FidelityProfile
from gaitforge.workers.spec_io import SpecError

logger = logging.getLogger(__name__)


@dataclass
class Row:
    """One profile's measurements (errors in rad, speeds per wall-clock s)."""

    label: str
    integrator: str
    timestep_ms: float
    accuracy: float | None
    fixed_step: bool
    steps_per_s: float
    realtime: float
    err_short: float
    err_long: float
    stable: bool
    health: str
    within: bool
    task: dict[str, float] = field(default_factory=dict)

    @property
    def error(self) -> float:
        """rad: the error judged against the tolerance (the larger window's)."""
        return max(self.err_short, self.err_long)

    def profile(self) -> FidelityProfile:
        return FidelityProfile(
            integrator=self.integrator,
            timestep=self.timestep_ms / 1e3,
            accuracy=self.accuracy,
            fixed_step=self.fixed_step,
        )


@dataclass
class SweepResult:
    scene: str
    backend: str
    tolerance: float
    size: SweepSize
    reference: dict
    rows: list[Row]
    model: list[dict]
    recommended: Row | None
    challenge: dict | None = None
    task_tolerance: float | None = None
    machine: str = field(default_factory=lambda: f"{platform.machine()} {platform.processor()}")

    def to_json(self) -> dict:
        out = asdict(self)
        out["rows"] = [{**asdict(r), "error": r.error} for r in self.rows]
        rec = self.recommended
        out["recommended"] = {**asdict(rec), "error": rec.error} if rec else None
        return out


def save_recommendation(result: SweepResult) -> tuple[saved_profiles.SavedProfile, Path] | None:
    """Save the recommended profile, if any, as ``<scene>-<backend>-tol<tolerance>`` in the
    profile directory (``workers.scenes.saved_profiles``), where scenes find it by name or
    with ``fidelity: auto``; returns it and its file."""
    best = result.recommended
    if best is None:
        return None
    saved = saved_profiles.SavedProfile(
        name=saved_profiles.saved_name(result.scene, result.backend, result.tolerance),
        scene=result.scene,
        backend=result.backend,
        tolerance=result.tolerance,
        profile=best.profile(),
        error=best.error,
        steps_per_s=best.steps_per_s,
    )
    return saved, saved_profiles.save(saved)


def _task_summary(stats: TaskStats, ref: TaskStats) -> dict[str, float]:
    out = stats.summary()
    dd, dh = difference(stats.distance, ref.distance)
    gd, gh = difference(stats.peak_grf, ref.peak_grf)
    out.update(distance_vs_ref=dd, distance_vs_ref_ci=dh, grf_vs_ref=gd, grf_vs_ref_ci=gh)
    return out


def run_sweep(
    scene: Scene,
    backend: str,
    tolerance: float,
    grid: list[FidelityProfile],
    size: SweepSize,
    on_step: Callable[[str], None] | None = None,
    model_checks: bool = True,
    task_tolerance: float | None = None,
) -> SweepResult:
    """Measure ``grid`` on ``scene``/``backend`` (see the module docstring).

    Raises:
        SpecError: empty grid, tolerance <= 0, or a backend the scene does not run on.
    """
    if tolerance <= 0:
        raise SpecError(f"--tolerance: must be > 0 rad, got {tolerance:g}")
    if task_tolerance is not None and task_tolerance < 0:
        raise SpecError(f"--task-tolerance: must be >= 0 m, got {task_tolerance:g}")
    if not grid:
        raise SpecError(f"grid: no profile to sweep for scene {scene.name!r} on {backend}")
    if backend not in scene.backends:
        raise SpecError(f"--backend: scene {scene.name!r} runs on {scene.backends}")

    def note(text: str) -> None:
        logger.info(text)
        if on_step is not None:
            on_step(text)

    dt = 1.0 / scene.control_hz
    ref: Reference = converged_reference(scene, backend, tolerance, size.long)
    note(f"reference {describe(ref.profile)}: margin {ref.margin:.1f}")
    if not ref.converged:
        logger.warning(
            "reference %s not converged: refinement changes it by %.3g rad, margin %.1f < %g",
            describe(ref.profile),
            ref.refined_change,
            ref.margin,
            MARGIN,
        )
    ref_task, ref_speed = speed_runs(scene, backend, ref.profile, size.seeds, size.task_s, 1)
    note("reference task runs")
    rows = []
    for profile in grid:
        label = describe(profile)
        held = held_rollout(scene, backend, profile, size.long)
        stats, speed = speed_runs(scene, backend, profile, size.seeds, size.task_s, size.repeats)
        causes = dict(stats.health)
        if held.health != "ok":
            causes[f"held:{held.health}"] = 1
        err_long = rms_error(held, ref.rollout, size.long, dt)
        err_short = rms_error(held, ref.rollout, size.short, dt)
        stable = not causes
        health = ", ".join(f"{k}: {v}" for k, v in sorted(causes.items())) or "ok"
        task = _task_summary(stats, ref_task)
        task_ok = task_tolerance is None or abs(task["distance_vs_ref"]) <= task_tolerance
        rows.append(
            Row(
                label=label,
                integrator=profile.integrator,
                timestep_ms=profile.timestep * 1e3,
                accuracy=profile.accuracy,
                fixed_step=profile.fixed_step,
                steps_per_s=speed,
                realtime=speed / scene.control_hz,
                err_short=err_short,
                err_long=err_long,
                stable=stable,
                health=health,
                within=stable and max(err_short, err_long) <= tolerance and task_ok,
                task=task,
            )
        )
        note(label)
    model: list[dict] = []
    if model_checks:
        checks = [
            lambda: model_error.cross_simulator(scene, backend, ref.rollout, size.short, size.long),
            lambda: model_error.tendon(scene, backend, size.short, size.long),
            lambda: model_error.pruning(scene, backend, ref.rollout, size),
        ]
        for check in checks:
            diff = check()
            if diff is not None:
                model.append(asdict(diff))
                note(diff.what)
    fits = [r for r in rows if r.within]
    best = max(fits, key=lambda r: r.steps_per_s) if fits else None
    reference = {
        "profile": describe(ref.profile),
        "refined": describe(ref.refined_profile),
        "refined_change": ref.refined_change,
        "margin": ref.margin,
        "converged": ref.converged,
        "required_margin": MARGIN,
        "task": ref_task.summary(),
        "steps_per_s": ref_speed,
    }
    result = SweepResult(scene.name, backend, tolerance, size, reference, rows, model, best)
    result.task_tolerance = task_tolerance
    result.challenge = _versus_challenge(rows, best)
    return result


def _versus_challenge(rows: list[Row], best: Row | None) -> dict | None:
    """The recommended profile against the 2017 challenge's setting (OpenSim RK-Merson at
    accuracy 5e-5), where the grid holds it: speeds, errors and the speed-up."""
    challenge = NAMED_PROFILES["opensim"]["challenge2017"]
    row = next((r for r in rows if r.profile() == challenge), None)
    if row is None or best is None:
        return None
    return {
        "challenge": row.label,
        "challenge_steps_per_s": row.steps_per_s,
        "challenge_error": row.error,
        "recommended": best.label,
        "recommended_steps_per_s": best.steps_per_s,
        "recommended_error": best.error,
        "speedup": best.steps_per_s / row.steps_per_s,
    }


def remeasure(
    scene: Scene, backend: str, profile: FidelityProfile, short: float, long: float
) -> float:
    """The error of ``profile`` (rad, the larger of the two windows, s) against a fresh
    reference run."""
    ref = held_rollout(scene, backend, REFERENCE[backend], long)
    run = held_rollout(scene, backend, profile, long)
    dt = 1.0 / scene.control_hz
    return max(rms_error(run, ref, short, dt), rms_error(run, ref, long, dt))
