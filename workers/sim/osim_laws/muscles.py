"""OpenSim's muscle forces on MuJoCo: each muscle's passive fibre force (the scene's
``muscle_passive: opensim``) and its active force (``muscle_curves: opensim``) computed as
OpenSim's rigid-tendon ``Millard2012EquilibriumMuscle`` makes them and applied every physics
step, MuJoCo's own curves set to zero. MuJoCo still integrates the activation (its muscle
activation dynamics are the same first-order law with the body's time constants).

For a muscle of peak force ``F`` (N), optimal fibre length ``l_opt`` (m), tendon slack
length ``l_ts`` (m), pennation ``a0`` at optimal length and top speed ``v_max`` (optimal
lengths/s), at MuJoCo's musculotendon length ``l_mt`` (m), speed ``v_mt`` (m/s) and
activation ``act``:

- the fibre keeps its height ``h = l_opt sin(a0)``: along the tendon it is ``x = l_mt - l_ts``
  long, so ``l = sqrt(x^2 + h^2)`` and ``cos(a) = x / l``; it moves at ``v = cos(a) v_mt``,
  ``v~ = v / (v_max l_opt)`` normalised;
- passive: ``F (fpe(l / l_opt) + beta v~)``, ``fpe`` OpenSim's ``FiberForceLengthCurve`` as
  ``opensim.build`` shapes it after Thelen's, ``beta`` Millard's fibre damping
  :data:`FIBRE_DAMPING` (MuJoCo's quadratic cannot follow the curve: see ``muscle_curves``);
- active: ``F act fl(l / l_opt) fv(v~)``, Millard's default active force-length and
  force-velocity curves (MuJoCo's own shapes are 0.14-0.15 of peak force off them; fitted,
  ``muscle_curves: millard``, still 0.05);
- the tendon carries their sum times ``cos(a)`` (none where the sum is negative: a tendon
  does not push, as OpenSim's does not), turned into joint torques by MuJoCo's moment arms.

OpenSim's curves are tabulated once from its own curve objects (:data:`LENGTHS`,
:data:`SPEEDS`) and interpolated linearly.
"""

from __future__ import annotations

from functools import lru_cache

import mujoco
import numpy as np
from gaitforge.workers.bodies.schema import Muscle

LENGTHS = np.linspace(0.0, 4.0, 801)
"""normalised fibre lengths at which the length curves are tabulated (0.005 apart)"""
SPEEDS = np.linspace(-2.0, 2.0, 1601)
"""normalised fibre speeds (lengthening > 0) at which force-velocity is tabulated"""
FIBRE_DAMPING = 0.1
"""Millard2012EquilibriumMuscle's default ``fiber_damping`` (per normalised fibre speed)."""


@lru_cache(maxsize=64)
def opensim_passive_curve(strain: float, shape: float) -> np.ndarray:
    """[len(LENGTHS)] OpenSim's passive fibre force (fraction of peak force), for a muscle with
    Thelen's ``strain`` at one normalised force and ``shape``."""
    import opensim  # only scenes that ask for it pay for OpenSim's import
    from gaitforge.workers.sim.opensim.build import fit_passive_curve

    curve = opensim.FiberForceLengthCurve()
    fit_passive_curve(curve, strain, shape)
    return np.array([curve.calcValue(float(x)) for x in LENGTHS])


@lru_cache(maxsize=1)
def opensim_active_curves() -> tuple[np.ndarray, np.ndarray]:
    """Millard's default active force-length curve on :data:`LENGTHS` and force-velocity curve
    on :data:`SPEEDS` (fractions of peak force), as ``opensim.build``'s muscles have them."""
    import opensim

    muscle = opensim.Millard2012EquilibriumMuscle("curves", 1.0, 1.0, 1.0, 0.0)
    length, speed = muscle.getActiveForceLengthCurve(), muscle.getForceVelocityCurve()
    return (
        np.array([length.calcValue(float(x)) for x in LENGTHS]),
        np.array([speed.calcValue(float(v)) for v in SPEEDS]),
    )


def interpolate(table: np.ndarray, grid: np.ndarray, x: np.ndarray) -> np.ndarray:
    """[n] linear interpolation on the even ``grid`` at ``x`` ([n]), held at its ends, of
    ``table``: one curve ([len(grid)]) or one per entry of ``x`` ([n, len(grid)])."""
    place = np.clip((x - grid[0]) / (grid[1] - grid[0]), 0.0, len(grid) - 1.001)
    low = place.astype(int)
    frac = place - low
    if table.ndim == 2:
        rows = np.arange(len(x))
        return table[rows, low] * (1.0 - frac) + table[rows, low + 1] * frac
    return table[low] * (1.0 - frac) + table[low + 1] * frac


class OpenSimMuscles:
    """The forces of a compiled model's muscles (every actuator a muscle of ``muscles``,
    matched by name) on OpenSim's laws: the passive part, the active part or both, added to
    a generalized force vector. ``tension`` ([nu], N) holds the last call's tendon forces."""

    def __init__(
        self, model: mujoco.MjModel, muscles: list[Muscle], *, active: bool, passive: bool
    ) -> None:
        by_name = {m.name: m for m in muscles}
        kept = [by_name[model.actuator(k).name] for k in range(model.nu)]
        self.active, self.passive = active, passive
        self.peak = np.array([m.max_isometric_force for m in kept])
        self.optimal = np.array([m.optimal_fiber_length for m in kept])
        self.slack = np.array([m.tendon_slack_length for m in kept])
        self.height = self.optimal * np.sin([m.pennation_angle for m in kept])
        self.top_speed = np.array([m.max_contraction_velocity for m in kept]) * self.optimal
        self.passive_curves = np.stack(
            [opensim_passive_curve(m.passive_fibre_strain, m.passive_shape) for m in kept]
        )
        self.length_curve, self.speed_curve = opensim_active_curves()
        self.act_adr = model.actuator_actadr.copy()
        self.tension = np.zeros(model.nu)
        self._moment = np.zeros((model.nu, model.nv))

    def add(self, model: mujoco.MjModel, data: mujoco.MjData, qfrc: np.ndarray) -> None:
        """Add the tensions' torques at the present lengths, speeds and activations to
        ``qfrc`` ([nv]; after ``mj_step1``, whose moment arms and lengths it reads)."""
        along = np.maximum(data.actuator_length - self.slack, 1e-9)
        fibre = np.sqrt(along**2 + self.height**2)
        cos = along / fibre
        length = fibre / self.optimal
        speed = cos * data.actuator_velocity / self.top_speed
        force = np.zeros(model.nu)
        if self.passive:
            force += interpolate(self.passive_curves, LENGTHS, length) + FIBRE_DAMPING * speed
        if self.active:
            force += (
                data.act[self.act_adr]
                * interpolate(self.length_curve, LENGTHS, length)
                * interpolate(self.speed_curve, SPEEDS, speed)
            )
        # a tendon pulls and never pushes: as OpenSim's muscle, none where the fibre's
        # damping outweighs the rest (a relaxed fibre shortening fast)
        self.tension[:] = self.peak * np.maximum(force, 0.0) * cos
        mujoco.mju_sparse2dense(
            self._moment,
            data.actuator_moment,
            data.moment_rownnz,
            data.moment_rowadr,
            data.moment_colind,
        )
        qfrc -= self._moment.T @ self.tension  # MuJoCo's tension is a negative actuator force
