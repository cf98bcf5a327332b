"""The converged reference a sweep judges integration error against.

MuJoCo: RK4 at 0.05 ms. Joint limits make the legs' dynamics stiff, and the implicit
integrators converge to a different answer as their step shrinks (implicitfast at 0.1 and
0.25 ms both sit about 0.011 rad RMS from RK4 on walk-2d's held variant, while Euler
approaches RK4), so RK4 is the reference. OpenSim: Runge-Kutta-Merson at accuracy 1e-7.
Convergence is shown, not assumed: the reference is run again with its step halved (or its
accuracy tightened tenfold) and the change, RMS over the long window, must be at least
``MARGIN`` times smaller than the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

from gaitforge.workers.fidelity.held import Rollout, held_rollout, rms_error
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile

MARGIN = 10.0
"""The reference's own change on refinement must be this many times below the tolerance."""
REFERENCE = {
    "mujoco": FidelityProfile(integrator="rk4", timestep=0.00005),
    "opensim": FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=1e-7),
}


def refined(profile: FidelityProfile) -> FidelityProfile:
    """``profile`` with its step halved (fixed-step) or its accuracy tightened tenfold."""
    if profile.accuracy is None or profile.fixed_step:
        return profile.model_copy(update={"timestep": profile.timestep / 2})
    return profile.model_copy(update={"accuracy": profile.accuracy / 10})


@dataclass
class Reference:
    """The reference rollout and the evidence that it is converged.

    Attributes:
        profile: the reference setting.
        rollout: its held rollout (the one errors are measured against).
        refined_change: RMS joint-angle change (rad) over the long window when refined.
        margin: tolerance / refined_change (``inf`` if the change is 0).
        converged: ``margin >= MARGIN`` and both runs healthy.
    """

    profile: FidelityProfile
    rollout: Rollout
    refined_profile: FidelityProfile
    refined_change: float
    margin: float
    converged: bool


def converged_reference(
    scene: Scene, backend: str, tolerance: float, seconds: float, seed: int = 0
) -> Reference:
    """Run the reference and its refinement on the held variant for ``seconds``."""
    profile = REFERENCE[backend]
    base = held_rollout(scene, backend, profile, seconds, seed)
    finer_profile = refined(profile)
    finer = held_rollout(scene, backend, finer_profile, seconds, seed)
    change = rms_error(base, finer, seconds, 1.0 / scene.control_hz)
    margin = tolerance / change if change > 0 else float("inf")
    healthy = base.health == "ok" and finer.health == "ok"
    return Reference(profile, base, finer_profile, change, margin, healthy and margin >= MARGIN)
