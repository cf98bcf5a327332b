"""Simulator backends behind one protocol (see ``workers.sim.base.Simulator``).

The backends are sub-packages: ``mujoco`` (MuJoCo) and ``opensim`` (OpenSim). The modules
here are backend-neutral: ``base`` (the protocol and what it returns), ``faults`` (fault injection),
``muscle_curves`` (the curves both backends fit) and ``pose`` (the pelvis's orientation);
:func:`make_simulator` picks a backend.
"""

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
    injection when a test asks for it: ``workers.sim.faults``)."""
    from gaitforge.workers.sim.faults import FaultySimulator, injected_faults

    sim = _backend_simulator(scene, backend)
    fault = injected_faults()
    if fault is not None:
        return FaultySimulator(sim, fault)  # type: ignore[return-value]
    return sim


def _backend_simulator(scene: Scene, backend: str) -> Simulator:
    if backend == "mujoco":
        from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

        return MujocoSimulator(scene)
    if backend == "opensim":
        from gaitforge.workers.sim.opensim.simulator import (
            OpenSimSimulator,  # lazy: imports OpenSim
        )

        return OpenSimSimulator(scene)
    raise ValueError(f"backend: unknown {backend!r}; allowed: ['mujoco', 'opensim']")
