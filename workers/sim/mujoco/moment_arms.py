"""Moment arms of a compiled MuJoCo model's muscles, and what follows from them.

Units are MuJoCo's: lengths in metres, hinge angles in radians, moment arms in metres
(m/rad for hinges, dimensionless m/m for slides). Joints driven by an equality coupling
(see :mod:`workers.sim.mujoco.lock`) are folded into their drivers.
"""

from __future__ import annotations

import logging
import re

import mujoco
import numpy as np
from gaitforge.workers.sim.mujoco.lock import _HINGE_SLIDE, _name, coupled_qpos, joint_couplings

logger = logging.getLogger(__name__)

MOMENT_ARM_TOL = 1e-4
"""|dL/dq| (m per rad or m per m) above which a muscle is said to span a joint."""

_DEFAULT_POSES = 5
_DEFAULT_SEED = 0
_SIDE_SUFFIX = re.compile(r"_[rlRL]$")
_UNLIMITED_HINGE_SPAN = 0.5  # rad either side of qpos0, for joints without a range
_UNLIMITED_SLIDE_SPAN = 0.02  # m either side of qpos0


def muscle_ids(model: mujoco.MjModel) -> list[int]:
    """Actuators with muscle activation dynamics, gain or bias."""
    return [
        i
        for i in range(model.nu)
        if model.actuator_dyntype[i] == mujoco.mjtDyn.mjDYN_MUSCLE
        or model.actuator_gaintype[i] == mujoco.mjtGain.mjGAIN_MUSCLE
        or model.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_MUSCLE
    ]


def _mirror_key(name: str) -> str:
    """Joint name without a trailing side suffix (``_r``/``_l``/``_R``/``_L``)."""
    return _SIDE_SUFFIX.sub("", name)


def _sample_poses(model: mujoco.MjModel, n_poses: int, seed: int) -> np.ndarray:
    """``qpos0`` then ``n_poses - 1`` random poses, hinge/slide joints uniform in range.

    Each joint takes a uniform random fraction of its range; joints whose names differ
    only by a ``_r``/``_l`` suffix share the fraction, so a bilateral model gets mirrored
    poses and left/right muscles get the same verdicts. Joints without a range vary by
    +-0.5 rad / +-0.02 m about ``qpos0``; free and ball joints stay at ``qpos0``; joint
    couplings are applied to every pose.
    """
    rng = np.random.default_rng(seed)
    poses = np.tile(model.qpos0, (max(1, n_poses), 1))
    fractions: dict[str, np.ndarray] = {}
    for jid in range(model.njnt):
        jtype = int(model.jnt_type[jid])
        if jtype not in _HINGE_SLIDE:
            continue
        adr = model.jnt_qposadr[jid]
        if model.jnt_limited[jid]:
            lo, hi = model.jnt_range[jid]
        else:
            span = (
                _UNLIMITED_HINGE_SPAN
                if jtype == mujoco.mjtJoint.mjJNT_HINGE
                else _UNLIMITED_SLIDE_SPAN
            )
            lo, hi = model.qpos0[adr] - span, model.qpos0[adr] + span
        key = _mirror_key(_name(model, mujoco.mjtObj.mjOBJ_JOINT, jid)) or f"#{jid}"
        if key not in fractions:
            fractions[key] = rng.uniform(0.0, 1.0, size=len(poses) - 1)
        poses[1:, adr] = lo + fractions[key] * (hi - lo)
    return np.array([coupled_qpos(model, qpos) for qpos in poses])


def _coupling_map(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``T[dof, k] = d q_dof / d q_k`` for free (undriven) dofs ``k`` at ``qpos``.

    Driven hinge/slide dofs get the chain-rule row of their driver; driven dofs' columns
    are zero, so ``J @ T`` is the effective (total) derivative with respect to the
    independent coordinates.
    """
    T = np.eye(model.nv)
    couplings = joint_couplings(model)
    driven_dofs = [model.jnt_dofadr[d] for d, _, _ in couplings]
    T[:, driven_dofs] = 0.0
    for _ in range(max(1, len(couplings))):
        for driven, driver, coef in couplings:
            row = model.jnt_dofadr[driven]
            if driver < 0:
                T[row] = 0.0
                continue
            x = qpos[model.jnt_qposadr[driver]] - model.qpos0[model.jnt_qposadr[driver]]
            slope = np.polyval(np.polyder(coef[::-1]), x)
            T[row] = slope * T[model.jnt_dofadr[driver]]
    return T


def muscle_moment_arms(
    model: mujoco.MjModel, n_poses: int = _DEFAULT_POSES, seed: int = _DEFAULT_SEED
) -> tuple[list[int], np.ndarray]:
    """Effective muscle length derivatives ``dL/dq`` at sampled poses.

    Args:
        model: Compiled model.
        n_poses: ``qpos0`` plus ``n_poses - 1`` random poses (see ``_sample_poses``).
        seed: Seed of the random poses.

    Returns:
        ``(muscle actuator ids, arms)`` with ``arms[pose, muscle, dof]`` in m/rad (hinge)
        or m/m (slide): the derivative of the actuator length (divided by its gear) with
        respect to each independent dof, driven dofs folded into their drivers.
    """
    ids = muscle_ids(model)
    data = mujoco.MjData(model)
    poses = _sample_poses(model, n_poses, seed)
    arms = np.zeros((len(poses), len(ids), model.nv))
    moment = np.zeros((model.nu, model.nv))
    gear = model.actuator_gear[ids, 0]
    gear = np.where(np.abs(gear) > 0, gear, 1.0)
    for p, qpos in enumerate(poses):
        data.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, data)
        mujoco.mju_sparse2dense(
            moment, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind
        )
        arms[p] = (moment[ids] / gear[:, None]) @ _coupling_map(model, qpos)
    return ids, arms


def _spannable_joints(model: mujoco.MjModel) -> list[int]:
    driven = {d for d, _, _ in joint_couplings(model)}
    return [
        j for j in range(model.njnt) if int(model.jnt_type[j]) in _HINGE_SLIDE and j not in driven
    ]


def muscle_spans(
    model: mujoco.MjModel,
    n_poses: int = _DEFAULT_POSES,
    seed: int = _DEFAULT_SEED,
    tol: float = MOMENT_ARM_TOL,
) -> dict[str, list[str]]:
    """For each muscle, the hinge/slide joints it has a moment arm about.

    A muscle spans a joint if ``|dL/dq| > tol`` at ``qpos0`` or at any of the random
    poses. Joints driven by an equality coupling are not listed: their effect is folded
    into the driver (MyoLeg's vasti insert on the patella, whose joints are driven by
    ``knee_angle``, so they span ``knee_angle``). Free and ball joints are skipped.

    Args:
        model: Compiled model.
        n_poses: Number of poses including ``qpos0``.
        seed: Seed of the random poses.
        tol: Threshold on ``|dL/dq|`` (m/rad or m/m).

    Returns:
        Muscle actuator name -> joint names (model order).
    """
    ids, arms = muscle_moment_arms(model, n_poses, seed)
    peak = np.abs(arms).max(axis=0) if len(ids) else np.zeros((0, model.nv))
    joints = _spannable_joints(model)
    return {
        _name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, aid): [
            _name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
            for j in joints
            if peak[m, model.jnt_dofadr[j]] > tol
        ]
        for m, aid in enumerate(ids)
    }
