"""Coupled dofs of a neutral body (``Dof.coupled``) as MuJoCo joint equality constraints.

A coupled dof stays a joint of the model (unlimited), held to its driver by an
``<equality><joint>`` named ``couple_<dof>`` (``joint1`` the coupled dof, ``joint2`` its
driver). MuJoCo's joint equality is a polynomial, ``y - y0 = a0 + a1 (x - x0) + ... +
a4 (x - x0)^4`` with ``x0``, ``y0`` the joints' ``qpos0``; the builder leaves every joint's
``ref`` at 0, so ``qpos0`` is 0 and the constraint reads ``y = poly(x)``. The polynomial is
the least-squares quartic through the function (a ``Linear`` exactly, a ``Spline`` within
the error :func:`coupling_fits` reports) sampled over the driver's range; beyond that range
the polynomial is extrapolated, where OpenSim's spline goes on linearly.

The constraint is soft like every MuJoCo constraint, and softer than its ``solref`` says:
MuJoCo scales its regularisation by an estimate of the constraint's inverse inertia taken at
``qpos0`` that adds the driver's whole inverse inertia (for a knee's translation, the
shank's 20 1/kg about its centre of mass where the true value is about 1). With MuJoCo's
default ``solref`` (0.02, 1) and ``solimp`` (0.9, 0.95) a hanging shank on a knee whose
translations follow gait10dof18musc's splines sat 12 mm off the polynomial;
:data:`COUPLING_SOLREF` and :data:`COUPLING_SOLIMP` bring that to 6e-6 m at rest and 8e-6 m
while it swings, at every fidelity profile's timestep
(``tests/workers/sim/test_mujoco_build_imported.py``), well below a spline's fit error
(3e-4 m for that knee's ``tx``). Implicit integrators apply joint and tendon damping after
the constraint solver, so a damped driver's coupled dofs lag a little more while it moves
(5e-5 m with a damped knee at the ``fast`` profile's 5 ms step).

Light segments that carry large forces follow less closely: the error grows with the load
and with the coupled dof's inverse inertia. Whole imported bodies dropped from their default
pose (0.5 s, the ``default`` profile: implicitfast, 2 ms) kept gait10dof18musc's and
gait2392's knee translations within 7e-4 m, but Rajagopal2016's patella (86 g, pulled by
the quadriceps, whose tendon damping implicitfast applies after the solver) turned up to
0.6 rad off its polynomial (0.03 rad with rk4). Such a body needs a finer look before it is
trusted on MuJoCo.

A **carrier** (:func:`add_carrier`) moves a muscle's moving path point the same way: a
near-massless body on the point's segment whose slides are coupled dofs of the point's
coordinate. The muscle pulls on it, and implicit integrators apply its tendon's damping
(``0.1 F_max / (v_max l_opt)``, hundreds of N s/m) after the constraint solver, so the slides
carry an armature (:data:`CARRIER_ARMATURE`) or they lag: gait10dof18musc hung by its pelvis,
its muscles excited at random for 2 s (implicitfast, 2 ms), kept its carriers within 64 mm
of their quartics at 0.1 kg, 8 mm at 1 kg and 0.8 mm at 10 kg, its knee translations
within 4.4 mm either way (13 to 18 mm at 5 ms); with rk4 both within 0.7 mm at 0.1 kg.
The armature adds ``armature * |dp/dq|^2`` to the knee's inertia (up to 0.01 kg m^2 a
carrier at 1 kg). The script: ``bench/carrier_drift.py``.

:func:`set_coupled_qpos` places the coupled joints exactly, for resets and for kinematic
comparisons.

Locking a driver (``workers.sim.mujoco.lock.lock_joints``) locks its coupled dofs too, at
``poly(value)``: ``lock_joints`` follows every active joint equality.

Units: hinge values in radians, slide values in metres (``qpos`` units).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.sim.mujoco.lock import joint_couplings
from numpy.polynomial.polynomial import polyder, polyfit, polyval

logger = logging.getLogger(__name__)

COUPLING_PREFIX = "couple_"
"""Name of a coupled dof's equality constraint: ``couple_<dof>``."""
POLY_DEGREE = 4
"""MuJoCo's joint equality holds a polynomial of degree 4 (five coefficients)."""
FIT_SAMPLES = 2001
"""Points over the driver's range where the polynomial is fitted and its error measured."""
COUPLING_SOLREF = (0.01, 1.0)
"""``(time constant s, damping ratio)``: the stiffest time constant MuJoCo keeps unchanged at
every fidelity profile's timestep (it raises it to twice the timestep: 0.005 s at ``fast``),
critically damped. The static error under a load scales with its square."""
COUPLING_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
"""Impedance at MuJoCo's largest (its default for equalities is 0.9 to 0.95): the static
error under a load scales with ``1 - impedance``."""
CARRIER_SUFFIX = "_carrier"
"""Name of a moving point's carrier body: ``<site>_carrier``."""
CARRIER_MASS = 1e-6
"""kg: a moving point's carrier body (MuJoCo needs a mass on a body with dofs)."""
CARRIER_INERTIA = 1e-12
"""kg m^2, each principal moment of a carrier body."""
CARRIER_ARMATURE = 1.0
"""kg on each slide of a carrier: what holds it to its functions under the muscle's pull and
its tendon's damping (see the module docstring)."""


@dataclass(frozen=True)
class CouplingFit:
    """The polynomial that stands for one coupled dof's function in MuJoCo.

    Attributes:
        driver: the free dof that drives the coupled one.
        coefficients: ``a0 .. a4`` (lowest order first) of ``y = sum a_k x^k``, with ``x``
            the driver's value (rad or m) and ``y`` the coupled dof's (rad or m); shape (5,).
        max_error: the largest ``|poly(x) - function(x)|`` over the driver's range (rad or m).
        driver_range: the range fitted over (rad or m).
    """

    driver: str
    coefficients: tuple[float, ...]
    max_error: float
    driver_range: tuple[float, float]

    def __call__(self, x: np.ndarray | float) -> np.ndarray:
        """The polynomial at driver values ``x`` (any shape; same shape out)."""
        return polyval(np.asarray(x, dtype=float), self.coefficients)


def fit_polynomial(
    function: Linear | Spline, driver_range: tuple[float, float], driver: str = ""
) -> CouplingFit:
    """The least-squares quartic through ``function`` over ``driver_range`` (and its error).

    The samples are :data:`FIT_SAMPLES` evenly spaced points plus a spline's knots inside
    the range, so its worst error between knots and at them is seen.
    """
    lo, hi = driver_range
    x = np.linspace(lo, hi, FIT_SAMPLES)
    if isinstance(function, Spline):
        knots = np.asarray(function.x)
        x = np.union1d(x, knots[(knots > lo) & (knots < hi)])
    y = evaluate(function, x)
    coefficients = polyfit(x, y, POLY_DEGREE)
    error = float(np.max(np.abs(polyval(x, coefficients) - y)))
    return CouplingFit(
        driver=driver,
        coefficients=tuple(float(c) for c in coefficients),
        max_error=error,
        driver_range=(float(lo), float(hi)),
    )


def coupling_fits(body: Body) -> dict[str, CouplingFit]:
    """Every coupled dof of ``body`` and the polynomial MuJoCo uses for it (for the import
    report: ``max_error`` is how far the MuJoCo body's kinematics may be from OpenSim's)."""
    fits: dict[str, CouplingFit] = {}
    for joint in body.ordered_joints():
        for dof in joint.dofs:
            if dof.coupled is None:
                continue
            driver = body.dof(dof.coupled.coordinate)
            fits[dof.name] = fit_polynomial(dof.coupled.function, driver.range, driver.name)
    return fits


def add_couplings(spec: mujoco.MjSpec, body: Body) -> dict[str, CouplingFit]:
    """One joint equality ``couple_<dof>`` per coupled dof of ``body`` (its joints must be in
    ``spec`` already, with ``ref`` 0). Returns the fits (:func:`coupling_fits`)."""
    fits = coupling_fits(body)
    for coupled, fit in fits.items():
        _add_coupling(spec, coupled, fit.driver, fit.coefficients)
        logger.debug(
            "coupling %s = poly(%s), worst fit error %.3g over %s",
            coupled,
            fit.driver,
            fit.max_error,
            fit.driver_range,
        )
    return fits


def add_carrier(
    spec: mujoco.MjSpec,
    parent: mujoco.MjsBody,
    name: str,
    driver: str,
    quartics: tuple[tuple[float, ...], ...],
) -> mujoco.MjsBody:
    """A carrier for a moving path point on ``parent``: a body ``<name>_carrier`` whose
    origin is the point, at ``(x, y, z) = quartics(q)`` (m) in ``parent``'s frame, ``q``
    the value of the free dof ``driver`` (its joint in ``spec`` already, ``ref`` 0). Each
    coordinate of the point that varies is a slide ``<name>_<axis>`` held to its quartic by
    an equality ``couple_<name>_<axis>``; one that does not is the body's offset. The
    carrier weighs :data:`CARRIER_MASS`; each slide carries :data:`CARRIER_ARMATURE`. Put
    the point's site at the carrier's origin."""
    carrier = parent.add_body(
        name=f"{name}{CARRIER_SUFFIX}",
        mass=CARRIER_MASS,
        inertia=[CARRIER_INERTIA] * 3,
        explicitinertial=True,
    )
    offset = [0.0, 0.0, 0.0]
    for k, coefficients in enumerate(quartics):
        if not any(coefficients[1:]):
            offset[k] = coefficients[0]
            continue
        slide = f"{name}_{'xyz'[k]}"
        carrier.add_joint(
            name=slide,
            type=mujoco.mjtJoint.mjJNT_SLIDE,
            axis=np.eye(3)[k].tolist(),
            limited=0,
            armature=CARRIER_ARMATURE,
        )
        _add_coupling(spec, slide, driver, coefficients)
    carrier.pos = offset
    return carrier


def _add_coupling(
    spec: mujoco.MjSpec, coupled: str, driver: str, coefficients: tuple[float, ...]
) -> None:
    """The joint equality ``couple_<coupled>``: ``coupled = sum a_k driver^k`` (``a_k`` the
    ``coefficients``, lowest order first)."""
    data = np.zeros(mujoco.mjNEQDATA)
    data[: POLY_DEGREE + 1] = coefficients
    spec.add_equality(
        name=f"{COUPLING_PREFIX}{coupled}",
        type=mujoco.mjtEq.mjEQ_JOINT,
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        name1=coupled,
        name2=driver,
        data=data.tolist(),
        solref=list(COUPLING_SOLREF),
        solimp=list(COUPLING_SOLIMP),
    )


def set_coupled_qpos(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Set every coupled joint's ``qpos`` (and ``qvel``) from its driver by the polynomial.

    ``y = y0 + poly(x - x0)`` and ``dy/dt = poly'(x - x0) dx/dt`` for each active ``couple_*``
    joint equality (``x0``, ``y0`` the joints' ``qpos0``), so the constraints start
    satisfied. Drivers are free dofs, so one pass suffices. Nothing else is recomputed:
    call ``mj_forward`` (or ``mj_kinematics``) afterwards for positions that depend on it.
    Joint equalities not made by :func:`add_couplings` (MyoSuite's) are left alone.
    """
    for coupled, driver, coefficients in joint_couplings(model, COUPLING_PREFIX):
        qc, qd = model.jnt_qposadr[coupled], model.jnt_qposadr[driver]
        x = data.qpos[qd] - model.qpos0[qd]
        data.qpos[qc] = model.qpos0[qc] + polyval(x, coefficients)
        slope = polyval(x, polyder(coefficients))
        data.qvel[model.jnt_dofadr[coupled]] = slope * data.qvel[model.jnt_dofadr[driver]]
