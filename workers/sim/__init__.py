"""Simulator backends behind one protocol (see ``workers.sim.base.Simulator``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim.base import CompileReport, Health, SimState, Simulator

if TYPE_CHECKING:
    from gaitforge.workers.scenes.spec import Scene

__all__ = [
    "CompileReport",
    "FidelityProfile",
    "Health",
    "SimState",
    "Simulator",
    "make_simulator",
]


def make_simulator(scene: Scene, backend: str = "mujoco") -> Simulator:
    """Compile ``scene`` for ``backend`` and return its simulator (wrapped for fault
    injection when the scene asks for it, in tests)."""
    sim = _backend_simulator(scene, backend)
    if scene.fault is not None:
        from gaitforge.workers.sim.faults import FaultySimulator  # lazy: test-only

        return FaultySimulator(sim, scene.fault)  # type: ignore[return-value]
    return sim


def _backend_simulator(scene: Scene, backend: str) -> Simulator:
    if backend == "mujoco":
        from gaitforge.workers.sim.mujoco import MujocoSimulator

        return MujocoSimulator(scene)
    if backend == "opensim":
        from gaitforge.workers.sim.opensim import OpenSimSimulator  # lazy: imports OpenSim

        return OpenSimSimulator(scene)
    raise ValueError(f"backend: unknown {backend!r}; allowed: ['mujoco', 'opensim']")
