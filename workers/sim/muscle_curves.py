"""The passive fibre force of Thelen 2003 (the reference's muscle), which both backends fit,
and MuJoCo's active force-length and force-velocity curves fitted to OpenSim-Millard's (a
scene option).

MuJoCo's and OpenSim-Millard's muscles have their own curve shapes; each builder picks its
parameters so that its passive curve follows this one, so that the two simulators (and the
2017 reference) agree on how hard a stretched, relaxed muscle pulls.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np


def thelen_passive(norm_length: np.ndarray, strain: float, shape: float) -> np.ndarray:
    """Passive force / max isometric force at normalised fibre length(s).

    ``strain``: fibre strain at which it equals 1 (Thelen's FmaxMuscleStrain); ``shape``:
    Thelen's exponential shape factor (KshapePassive).
    """
    x = np.clip((np.asarray(norm_length, dtype=float) - 1.0) / strain, 0.0, None)
    return (np.exp(shape * x) - 1.0) / (math.exp(shape) - 1.0)


def thelen_passive_stiffness_at_one(strain: float, shape: float) -> float:
    """Slope (per unit normalised length) of :func:`thelen_passive` where it reaches 1."""
    return shape / strain * math.exp(shape) / (math.exp(shape) - 1.0)


def mujoco_passive(norm_length: np.ndarray, lmax: float, fpmax: float) -> np.ndarray:
    """MuJoCo's muscle passive force / peak force (engine_util_misc.c, ``mju_muscleBias``):
    quadratic from 1 to the midpoint ``b = (1 + lmax) / 2``, then linear."""
    length = np.asarray(norm_length, dtype=float)
    b = 0.5 * (1.0 + lmax)
    x = (length - 1.0) / (b - 1.0)
    return fpmax * np.where(length <= 1.0, 0.0, np.where(length <= b, 0.5 * x**2, 0.5 + (x - 1.0)))


FIT_UP_TO = 0.6
"""Fraction of the strain at one norm force over which MuJoCo's curve is fitted: the range
relaxed muscles reach in gait (gastrocnemius at standing is near 0.6). MuJoCo's curve turns
linear where Thelen's keeps growing exponentially, so beyond it MuJoCo's is the softer."""


def fit_mujoco_fpmax(
    strain: float, shape: float, lmax: float, up_to: float = FIT_UP_TO, points: int = 41
) -> float:
    """Least-squares ``fpmax`` so that MuJoCo's passive curve follows Thelen's over fibre
    strains from 0 to ``up_to * strain`` (``points`` lengths)."""
    lengths = np.linspace(1.0, 1.0 + up_to * strain, points)
    return _least_squares_fpmax(lengths, thelen_passive(lengths, strain, shape), lmax)


def _least_squares_fpmax(lengths: np.ndarray, target: np.ndarray, lmax: float) -> float:
    """``fpmax`` of MuJoCo's passive curve (``lmax`` given) closest to ``target`` at
    ``lengths`` (MuJoCo's normalised lengths) by least squares."""
    unit = mujoco_passive(lengths, lmax, 1.0)
    return float(unit @ target / (unit @ unit))


WHOLE_STRAIN_POINTS = 61
"""Fibre lengths, 1 to 1 + strain, that :func:`fit_mujoco_passive_whole` fits over."""


def thelen_passive_on_tendon(
    projected: np.ndarray, strain: float, shape: float, pennation: float
) -> np.ndarray:
    """Thelen's passive force along the tendon, as a fraction of MuJoCo's peak force
    (``F_max cos(pennation)``), at MuJoCo's normalised lengths ``projected`` (the fibre's
    length along the tendon over ``l_opt cos(pennation)``, ``mujoco.build``'s ``L0``).

    OpenSim's rigid-tendon Millard muscle keeps the fibre's height constant (``l_opt
    sin(pennation)``), so its fibre is ``sqrt((x cos a)^2 + sin(a)^2)`` optimal lengths long
    at MuJoCo's ``x``, shorter than ``x`` past 1, and pulls on the tendon times ``cos`` of its
    angle then, ``x cos(a) / fibre``: gait2d's gastrocnemius (17 degrees) standing is
    1.458 long to MuJoCo and 1.425 to OpenSim. With ``pennation`` 0 this is
    :func:`thelen_passive`."""
    x = np.asarray(projected, dtype=float)
    fibre = np.sqrt((x * math.cos(pennation)) ** 2 + math.sin(pennation) ** 2)
    return thelen_passive(fibre, strain, shape) * x / fibre


@lru_cache(maxsize=64)
def fit_mujoco_passive_whole(
    strain: float, shape: float, pennation: float = 0.0
) -> tuple[float, float]:
    """``(lmax, fpmax)`` of MuJoCo's passive curve (the muscle's ``biasprm``, apart from the
    active force's) fitted by least squares to Thelen's over its whole strain, 1 to
    ``1 + strain`` normalised fibre length (passive force 0 to 1): ``lmax`` on a 0.01 grid
    from 1.02 to 3, ``fpmax`` solved at each. The optimum is a pure quadratic over the strain
    (MuJoCo's curve bends no more than that): from ``lmax = 1 + 2 strain`` up the fitted
    lengths all lie on its quadratic part and only ``fpmax`` changes, by the same curve
    there (RMS 0.071 of peak force for Thelen's shape 4 at strains 0.6 and 1.0); the grid's
    pick among those (2.33 for 0.6, 2.99 for 1.0, gait2d's rectus femoris and vasti) sets only
    where the curve turns linear past the strain. The scene option ``muscle_passive: thelen``.

    With ``pennation`` (rad at optimal length), the target is Thelen's curve of the pennated
    fibre's own length, projected on the tendon (:func:`thelen_passive_on_tendon`), over the
    MuJoCo lengths whose fibre spans 1 to ``1 + strain``: ``muscle_passive: thelen-fibre``.

    :func:`fit_mujoco_fpmax` (the default) fits ``fpmax`` alone over the first
    :data:`FIT_UP_TO` of the strain, ``lmax`` shared with the active curve, and is the softer
    beyond it: gait2d's gastrocnemius at 1.6 optimal length pulls 0.44 of its peak force
    there against Thelen's 1.0; with this fit 0.77.
    """
    end = math.sqrt((1.0 + strain) ** 2 - math.sin(pennation) ** 2) / math.cos(pennation)
    lengths = np.linspace(1.0, end, WHOLE_STRAIN_POINTS)
    target = thelen_passive_on_tendon(lengths, strain, shape, pennation)

    def error(lmax: float) -> float:
        fpmax = _least_squares_fpmax(lengths, target, lmax)
        return float(np.sum((mujoco_passive(lengths, lmax, fpmax) - target) ** 2))

    lmax = min((float(x) for x in np.arange(1.02, 3.0, 0.01)), key=error)
    return lmax, _least_squares_fpmax(lengths, target, lmax)


MILLARD_ACTIVE_RANGE = (0.24, 1.87)
"""MuJoCo's ``lmin``, ``lmax`` of the active force (``gainprm``; the passive force keeps its
own, ``mujoco.build.ACTIVE_RANGE``) fitted to Millard 2012's default active force-length
curve (OpenSim's ``ActiveForceLengthCurve``, the OpenSim backend's muscle) over normalised
fibre lengths 0.5-1.6: least squares on a 0.01 grid, RMS 0.05 of isometric force. With
Millard's own end points (0.4441, 1.8) MuJoCo's piecewise quadratic is 0.15 off and a short
muscle much weaker than Millard's: 0.16 against 0.45 at 0.6, 0.42 against 0.77 at 0.7."""
MILLARD_VMAX_SCALE = 0.65
"""MuJoCo's ``vmax`` times this, with :data:`MILLARD_FVMAX`, makes its force-velocity curve
follow Millard 2012's default one (OpenSim's ``ForceVelocityCurve``) from 40 % of the
muscle's max contraction velocity shortening to 20 % lengthening: least squares on a 0.01
grid, RMS 0.05 of isometric force (MuJoCo's own curve: RMS 0.14, up to 0.19 above Millard's
while shortening at 0.1-0.3 vmax)."""
MILLARD_FVMAX = 1.27
"""MuJoCo's ``fvmax`` (force lengthening / isometric) in that fit; Millard's curve rises to
1.27 by 0.2 vmax lengthening (1.4 at vmax), MuJoCo's own stops at 1.2."""
FORCE_LENGTH_FIT_RANGE = (0.5, 1.6)
"""Normalised fibre lengths over which :data:`MILLARD_ACTIVE_RANGE` was fitted."""
FORCE_VELOCITY_FIT_RANGE = (-0.4, 0.2)
"""Fibre velocities (fraction of max contraction velocity, shortening negative) over which
:data:`MILLARD_VMAX_SCALE` and :data:`MILLARD_FVMAX` were fitted
(``tests/workers/sim/test_muscle_curves_millard.py`` refits all three against OpenSim's
curves)."""
