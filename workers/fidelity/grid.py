"""What a sweep measures: the grids of fidelity profiles per backend (full and ``--quick``),
and how long it measures each (``SweepSize``)."""

from __future__ import annotations

from dataclasses import dataclass

from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import NAMED_PROFILES, FidelityProfile

MUJOCO_INTEGRATORS = ("euler", "implicitfast", "implicit", "rk4")
MUJOCO_STEPS = (0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02)
"""s; a step that does not divide the scene's control period is skipped."""
OPENSIM_INTEGRATORS = ("rk-merson", "rk2", "rk3", "semi-explicit-euler2", "cpodes")
OPENSIM_ACCURACIES = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
OPENSIM_FIXED = (("rk2", 0.001), ("semi-explicit-euler2", 0.001))
"""(integrator, s): fixed-step runs, for the integrators whose fixed-step mode is useful."""
OPENSIM_MAX_STEP = 0.01
"""s: OpenSim's largest internal step in every error-controlled profile of the grid."""


@dataclass
class SweepSize:
    """How long each measurement runs.

    Attributes:
        short: s, the short error window; long: s, the long one (the held rollout length).
        seeds: task runs per profile; task_s: s simulated per task run.
        repeats: batches of task runs timed per profile (speed = their median).
    """

    short: float = 0.5
    long: float = 2.0
    seeds: int = 8
    task_s: float = 1.0
    repeats: int = 3

    @classmethod
    def for_run(cls, backend: str, quick: bool) -> SweepSize:
        if quick:
            return cls(short=0.1, long=0.5, seeds=2, task_s=0.2, repeats=1)
        if backend == "opensim":
            return cls(short=0.5, long=2.0, seeds=4, task_s=0.5, repeats=1)
        return cls()


QUICK_MUJOCO = (("implicitfast", 0.002), ("euler", 0.001), ("rk4", 0.001))
QUICK_OPENSIM = (("rk-merson", 1e-2), ("rk-merson", 1e-3))


def divides(scene: Scene, timestep: float) -> bool:
    """Whether ``timestep`` (s) divides the scene's control period."""
    n = 1.0 / (scene.control_hz * timestep)
    return abs(n - round(n)) < 1e-6 and round(n) >= 1


def sweep_grid(scene: Scene, backend: str, quick: bool = False) -> list[FidelityProfile]:
    """The profiles a sweep of ``scene`` on ``backend`` measures (the 2017 challenge's
    setting included on OpenSim)."""
    if backend == "mujoco":
        pairs = (
            QUICK_MUJOCO if quick else [(i, h) for i in MUJOCO_INTEGRATORS for h in MUJOCO_STEPS]
        )
        return [FidelityProfile(integrator=i, timestep=h) for i, h in pairs if divides(scene, h)]
    pairs_os = (
        QUICK_OPENSIM
        if quick
        else [(i, a) for i in OPENSIM_INTEGRATORS for a in OPENSIM_ACCURACIES]
    )
    grid = [
        FidelityProfile(integrator=i, timestep=OPENSIM_MAX_STEP, accuracy=a) for i, a in pairs_os
    ]
    if not quick:
        grid += [
            FidelityProfile(integrator=i, timestep=h, fixed_step=True) for i, h in OPENSIM_FIXED
        ]
        grid.append(NAMED_PROFILES["opensim"]["challenge2017"])
    return grid


def stress_grid(scene: Scene, backend: str, quick: bool = False) -> list[FidelityProfile]:
    """Profiles a stress run checks: each integrator at its cheapest setting in the sweep
    grid (largest step, loosest accuracy) and at the backend's named profiles."""
    named = list(NAMED_PROFILES[backend].values())
    if backend == "mujoco":
        steps = [h for h in MUJOCO_STEPS if divides(scene, h)]
        extremes = [FidelityProfile(integrator=i, timestep=max(steps)) for i in MUJOCO_INTEGRATORS]
        named = [p for p in named if divides(scene, p.timestep)]
    else:
        extremes = [
            FidelityProfile(
                integrator=i, timestep=OPENSIM_MAX_STEP, accuracy=max(OPENSIM_ACCURACIES)
            )
            for i in OPENSIM_INTEGRATORS
        ]
    if quick:
        return [extremes[0], named[0]]
    return list(dict.fromkeys([*extremes, *named]))
