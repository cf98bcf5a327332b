"""Fidelity profiles: how a backend integrates (integrator, timestep, accuracy).

A scene names a profile (``fidelity: default``), spells one out
(``fidelity: {integrator: rk4, timestep: 0.001}``), or gives one per backend
(``fidelity: {mujoco: fast, opensim: {integrator: rk-merson, timestep: 0.01, accuracy: 5e-5}}``).
``gaitforge fidelity sweep`` saves measured profiles that a scene names the same way, or
picks with ``fidelity: auto`` and ``fidelity_tolerance`` (``workers.scenes.saved_profiles``).
A scene is resolved on the driver, where it is loaded (``Scene.resolved``): its fidelity
becomes one concrete ``FidelityProfile`` before it reaches an actor or a checkpoint.

MuJoCo integrates with a fixed ``timestep``. OpenSim's integrators are error-controlled:
``accuracy`` is the error tolerance and ``timestep`` the largest internal step.
"""

from __future__ import annotations

from typing import Annotated, Literal

from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field

Backend = Literal["mujoco", "opensim"]
BACKENDS: tuple[str, ...] = ("mujoco", "opensim")

INTEGRATORS: dict[str, tuple[str, ...]] = {
    "mujoco": ("euler", "implicit", "implicitfast", "rk4"),
    "opensim": (
        "rk-merson",
        "rk-feldberg",
        "rk2",
        "rk3",
        "semi-explicit-euler2",
        "explicit-euler",
        "verlet",
        "cpodes",
    ),
}


class FidelityProfile(BaseModel):
    """One integration setting."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)

    integrator: str = Field(description="backend-specific integrator name")
    timestep: Annotated[float, Field(gt=0, le=0.05)] = Field(
        description="s: MuJoCo's step; OpenSim's largest internal step"
    )
    accuracy: Annotated[float, Field(gt=0, lt=1)] | None = Field(
        default=None, description="error tolerance of OpenSim's integrators"
    )
    fixed_step: bool = Field(
        default=False, description="OpenSim: integrate at a fixed ``timestep``, no error control"
    )


NAMED_PROFILES: dict[str, dict[str, FidelityProfile]] = {
    "mujoco": {
        "default": FidelityProfile(integrator="implicitfast", timestep=0.002),
        "fast": FidelityProfile(integrator="implicitfast", timestep=0.005),
        "accurate": FidelityProfile(integrator="rk4", timestep=0.0005),
    },
    "opensim": {
        "default": FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=1e-3),
        "fast": FidelityProfile(integrator="semi-explicit-euler2", timestep=0.01, accuracy=1e-2),
        "accurate": FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=1e-6),
        "challenge2017": FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=5e-5),
    },
}

Fidelity = str | FidelityProfile | dict[Backend, str | FidelityProfile]


def check_profile(profile: FidelityProfile, backend: str) -> FidelityProfile:
    """``profile`` if it is a valid setting for ``backend``; raises ``ValueError`` if not."""
    allowed = INTEGRATORS[backend]
    if profile.integrator not in allowed:
        raise ValueError(
            f"fidelity.integrator: {profile.integrator!r} is not a {backend} integrator; "
            f"allowed: {list(allowed)}"
        )
    if backend == "opensim" and profile.accuracy is None and not profile.fixed_step:
        raise ValueError("fidelity.accuracy: OpenSim's integrators need an accuracy")
    return profile
