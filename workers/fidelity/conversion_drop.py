"""The relaxed drop of a conversion: the root joint's coordinates (and those OpenSim locks)
held at their defaults, no excitation, no contact, both simulators let go for a while and
every other coordinate's trajectory compared.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np
import opensim
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.fidelity.conversion_report import Drop, root_mean_square
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, OpenSimSide
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.lock import lock_joints

logger = logging.getLogger(__name__)

DROP_SAMPLE_S = 0.01
"""s between the samples of the relaxed drop's trajectories"""
DROP_ACCURACY = 1e-3
"""OpenSim's integrator accuracy in the relaxed drop (error-controlled Runge-Kutta-Merson)"""
DROP_MUJOCO_TIMESTEP = 0.001
"""s, MuJoCo's step in the relaxed drop (``implicitfast`` integrator)"""


def relaxed_drop(osim_path: Path, body: Body, posed: OpenSimSide, duration: float) -> Drop:
    """Both simulators let go from the default pose, the root and OpenSim's locked
    coordinates held, no excitation, no contact (MuJoCo's contacts disabled)."""
    root = [d.name for d in body.ordered_joints()[0].dofs]
    defaults = posed.defaults()
    wanted = {c for c in [*root, *posed.default_locked] if c in posed.free}
    spec = build_spec(body)
    note = ""
    try:
        removed = lock_joints(spec, {c: defaults[c] for c in wanted if c in body.dof_names})
    except ValueError as exc:  # a locked joint after a free one in its body
        note = f"OpenSim's locked coordinates left free on both sides ({exc})"
        wanted = {c for c in root if c in posed.free}
        spec = build_spec(body)
        removed = lock_joints(spec, {c: defaults[c] for c in wanted})
    absent = {c for c in posed.free if c not in body.dof_names}
    locked = frozenset(wanted | absent)
    model = spec.compile()
    model.opt.timestep = DROP_MUJOCO_TIMESTEP
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    compared = [c for c in posed.free if c not in locked and c not in removed]
    samples = max(1, round(duration / DROP_SAMPLE_S))
    minimum = {name: posed.minimum_activation(name) for name in posed.muscles}
    trajectory_mj = _drop_mujoco(model, defaults, minimum, compared, samples)
    trajectory_os, failure = _drop_opensim(osim_path, locked, compared, samples)
    if failure:
        note = "; ".join(n for n in (note, f"OpenSim failed: {failure}") if n)
    rms = {
        c: root_mean_square(trajectory_mj[:, i] - trajectory_os[:, i])
        if np.all(np.isfinite(trajectory_mj[:, i])) and np.all(np.isfinite(trajectory_os[:, i]))
        else math.inf
        for i, c in enumerate(compared)
    }
    slides = [c for c in compared if not posed.rotational(c)]
    return Drop(samples * DROP_SAMPLE_S, sorted(locked), rms, slides, note)


def _drop_mujoco(
    model: mujoco.MjModel,
    defaults: Mapping[str, float],
    activations: Mapping[str, float],
    compared: list[str],
    samples: int,
) -> np.ndarray:
    """[samples, len(compared)] MuJoCo's coordinates after each :data:`DROP_SAMPLE_S`, each
    muscle's control and activation held at ``activations`` (OpenSim's minimum: what its
    activation stays at without excitation)."""
    side = MujocoSide(model)
    side.set_pose(defaults)
    side.data.act[:] = 0.0
    side.data.ctrl[:] = 0.0
    side.tendon_forces(activations)  # sets act and ctrl by muscle name
    addresses = [model.jnt_qposadr[side.joints[c]] for c in compared]
    steps = max(1, round(DROP_SAMPLE_S / model.opt.timestep))
    out = np.full((samples, len(compared)), math.nan)
    for k in range(samples):
        mujoco.mj_step(model, side.data, nstep=steps)
        if not np.all(np.isfinite(side.data.qpos)):
            logger.info("MuJoCo: the relaxed drop diverged at sample %d", k)
            break
        out[k] = side.data.qpos[addresses]
    return out


def _drop_opensim(
    path: Path, locked: frozenset[str], compared: list[str], samples: int
) -> tuple[np.ndarray, str]:
    """[samples, len(compared)] OpenSim's coordinates after each :data:`DROP_SAMPLE_S`,
    muscles at their minimum activation, fibres in equilibrium at the start; and why it
    stopped early ("" if it did not)."""
    side = OpenSimSide(path, locked)
    side.set_pose(side.defaults())
    for name, muscle in side.muscles.items():
        muscle.setActivation(side.state, side.minimum_activation(name))
    out = np.full((samples, len(compared)), math.nan)
    try:
        side.model.equilibrateMuscles(side.state)
        manager = opensim.Manager(side.model)
        manager.setWriteToStorage(False)
        manager.setPerformAnalyses(False)
        manager.setIntegratorAccuracy(DROP_ACCURACY)
        side.state.setTime(0.0)
        manager.initialize(side.state)
        for k in range(samples):
            state = manager.integrate((k + 1) * DROP_SAMPLE_S)
            out[k] = [side.coordinates[c].getValue(state) for c in compared]
    except Exception as exc:  # OpenSim raises RuntimeError when integration fails
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return out, first
    return out, ""
