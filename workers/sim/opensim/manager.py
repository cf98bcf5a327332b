"""How an OpenSim ``Manager`` integrates under a fidelity profile."""

from __future__ import annotations

import opensim
from gaitforge.workers.scenes.profiles import FidelityProfile

INTEGRATORS = {  # a fidelity profile's integrator name -> OpenSim's
    "rk-merson": opensim.Manager.IntegratorMethod_RungeKuttaMerson,
    "rk-feldberg": opensim.Manager.IntegratorMethod_RungeKuttaFeldberg,
    "rk2": opensim.Manager.IntegratorMethod_RungeKutta2,
    "rk3": opensim.Manager.IntegratorMethod_RungeKutta3,
    "semi-explicit-euler2": opensim.Manager.IntegratorMethod_SemiExplicitEuler2,
    "explicit-euler": opensim.Manager.IntegratorMethod_ExplicitEuler,
    "verlet": opensim.Manager.IntegratorMethod_Verlet,
    "cpodes": opensim.Manager.IntegratorMethod_CPodes,
}


def new_manager(
    model: opensim.Model, profile: FidelityProfile, state: opensim.State
) -> opensim.Manager:
    """A Manager for ``model`` started from ``state``: ``profile``'s integrator at its fixed
    step, or error-controlled at its accuracy (1e-3 if none) with its timestep as the largest
    step. It keeps no states table and runs no analyses (nothing reads them)."""
    manager = opensim.Manager(model)
    manager.setWriteToStorage(False)
    manager.setPerformAnalyses(False)
    manager.setIntegratorMethod(INTEGRATORS[profile.integrator])
    if profile.fixed_step:
        manager.setIntegratorFixedStepSize(profile.timestep)
    else:
        manager.setIntegratorAccuracy(profile.accuracy or 1e-3)
        manager.setIntegratorMaximumStepSize(profile.timestep)
    manager.initialize(state)
    return manager
