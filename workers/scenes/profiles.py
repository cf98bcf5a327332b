"""Fidelity profiles: how a backend integrates (integrator, timestep or accuracy).

A scene names a profile (``fidelity: default``) or spells one out
(``fidelity: {integrator: rk4, timestep: 0.001}``). Profiles are per backend; the
speed/accuracy sweeps of the fidelity issue add measured profiles to this table.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

MujocoIntegrator = Literal["euler", "implicit", "implicitfast", "rk4"]


class FidelityProfile(BaseModel):
    """One integration setting. ``timestep`` in seconds; ``accuracy`` for error-controlled
    integrators (OpenSim), ignored by fixed-step ones."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    integrator: str = Field(description="backend-specific integrator name")
    timestep: Annotated[float, Field(gt=0, le=0.05)] = Field(description="s")
    accuracy: Annotated[float, Field(gt=0, lt=1)] | None = None


MUJOCO_INTEGRATORS: tuple[str, ...] = ("euler", "implicit", "implicitfast", "rk4")

NAMED_PROFILES: dict[str, dict[str, FidelityProfile]] = {
    "mujoco": {
        "default": FidelityProfile(integrator="implicitfast", timestep=0.002),
        "fast": FidelityProfile(integrator="implicitfast", timestep=0.005),
        "accurate": FidelityProfile(integrator="rk4", timestep=0.0005),
    },
}

BACKENDS: tuple[str, ...] = ("mujoco", "opensim")
Backend = Literal["mujoco", "opensim"]


def resolve_profile(fidelity: str | FidelityProfile, backend: str) -> FidelityProfile:
    """A scene's fidelity field, resolved for ``backend``; raises ``ValueError`` if unknown."""
    if isinstance(fidelity, FidelityProfile):
        if backend == "mujoco" and fidelity.integrator not in MUJOCO_INTEGRATORS:
            raise ValueError(
                f"fidelity.integrator: {fidelity.integrator!r} is not a MuJoCo integrator; "
                f"allowed: {list(MUJOCO_INTEGRATORS)}"
            )
        return fidelity
    named = NAMED_PROFILES.get(backend, {})
    if fidelity not in named:
        raise ValueError(
            f"fidelity: unknown profile {fidelity!r} for backend {backend!r}; "
            f"allowed: {sorted(named)} or an explicit {{integrator, timestep}}"
        )
    return named[fidelity]
