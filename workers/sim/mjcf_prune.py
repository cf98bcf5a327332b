"""Generic pruning of a ``mujoco.MjSpec``: lock joints, remove muscles, restrict contacts.

These work on any spec (MyoSuite MJCF or one built from our neutral bodies) and keep it
compilable: references to what is removed (equality constraints, sensors, keyframe
entries, joint actuators) are removed or rewritten with it. Analysis functions
(:func:`muscle_spans`, :func:`planar_muscles`, :func:`model_size`) take a compiled
``mujoco.MjModel``.

Units are MuJoCo's: lengths in metres, hinge angles in radians (joint values are ``qpos``
values, whatever the spec's ``compiler angle``), moment arms in metres (m/rad for hinges,
dimensionless m/m for slides).

Joint couplings: MuJoCo's ``<equality><joint joint1=A joint2=B polycoef=c>`` enforces
``qA - qA0 = sum_k c_k (qB - qB0)^k`` with ``q0`` = ``qpos0`` (the joint ``ref``). A is
the *driven* joint, B the *driver*. MyoLeg drives its knee translations/rotations and
patella joints from ``knee_angle_*`` this way.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable, Sequence

import mujoco
import numpy as np

logger = logging.getLogger(__name__)

CONTACT_BIT = 2
"""Bit used by :func:`restrict_contacts`: kept geoms get ``contype=CONTACT_BIT,
conaffinity=0``, their partners ``contype=0, conaffinity=CONTACT_BIT``. A geom added
afterwards collides with the kept geoms only if its ``conaffinity`` has this bit."""

MOMENT_ARM_TOL = 1e-4
"""|dL/dq| (m per rad or m per m) above which a muscle is said to span a joint."""

_HINGE_SLIDE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_ZERO_DISPLACEMENT = 1e-12
_COUPLING_TOL = 1e-6
_DEFAULT_POSES = 5
_DEFAULT_SEED = 0
_SIDE_SUFFIX = re.compile(r"_[rlRL]$")
_UNLIMITED_HINGE_SPAN = 0.5  # rad either side of qpos0, for joints without a range
_UNLIMITED_SLIDE_SPAN = 0.02  # m either side of qpos0


# --------------------------------------------------------------------------- helpers


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, idx: int) -> str:
    return mujoco.mj_id2name(model, obj, idx) or ""


def _joint_couplings(model: mujoco.MjModel) -> list[tuple[int, int, np.ndarray]]:
    """Active joint couplings as ``(driven joint, driver joint or -1, polycoef[5])``."""
    return [
        (int(model.eq_obj1id[i]), int(model.eq_obj2id[i]), model.eq_data[i, :5].copy())
        for i in range(model.neq)
        if model.eq_type[i] == mujoco.mjtEq.mjEQ_JOINT and model.eq_active0[i]
    ]


def _coupled_value(
    model: mujoco.MjModel, driven: int, driver: int, coef: np.ndarray, driver_value: float
) -> float:
    q10 = model.qpos0[model.jnt_qposadr[driven]]
    if driver < 0:
        return float(q10 + coef[0])
    x = driver_value - model.qpos0[model.jnt_qposadr[driver]]
    return float(q10 + np.polyval(coef[::-1], x))


def _apply_couplings(model: mujoco.MjModel, qpos: np.ndarray) -> None:
    """Set every driven joint of ``qpos`` (in place) from its driver; resolves chains."""
    couplings = _joint_couplings(model)
    for _ in range(max(1, len(couplings))):
        for driven, driver, coef in couplings:
            drv = qpos[model.jnt_qposadr[driver]] if driver >= 0 else 0.0
            qpos[model.jnt_qposadr[driven]] = _coupled_value(model, driven, driver, coef, drv)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def _rot(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(vec, float), np.asarray(quat, float))
    return out


def _body_local_quat(spec: mujoco.MjSpec, body: mujoco.MjsBody) -> np.ndarray:
    """The body's orientation in its parent (or frame), whatever form the spec uses."""
    if body.alt.type == mujoco.mjtOrientation.mjORIENTATION_QUAT:
        quat = np.array(body.quat, dtype=float)
    else:
        quat = np.array(
            spec.resolve_orientation(spec.compiler.degree, spec.compiler.eulerseq, body.alt)
        )
    return quat / np.linalg.norm(quat)


def _fold_joint(
    pos: np.ndarray,
    quat: np.ndarray,
    jtype: int,
    anchor: np.ndarray,
    axis: np.ndarray,
    displacement: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Compose body frame ``(pos, quat)`` with a joint displaced by ``displacement``.

    Mirrors ``mj_kinematics``: a slide moves the frame along ``axis`` (body frame); a
    hinge rotates it about ``axis`` through ``anchor`` (both in the body frame).
    """
    if jtype == mujoco.mjtJoint.mjJNT_SLIDE:
        return pos + _rot(quat, axis * displacement), quat
    local = np.zeros(4)
    mujoco.mju_axisAngle2Quat(local, axis, displacement)
    new_quat = _quat_mul(quat, local)
    new_pos = pos + _rot(quat, anchor - _rot(local, anchor))
    return new_pos, new_quat / np.linalg.norm(new_quat)


def _rewrite_keys(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    *,
    drop_qpos: Sequence[int] = (),
    drop_qvel: Sequence[int] = (),
    drop_ctrl: Sequence[int] = (),
    drop_act: Sequence[int] = (),
) -> None:
    """Remove entries from every keyframe whose arrays have the full (old) size."""
    for key in spec.keys:
        for attr, size, drop in (
            ("qpos", model.nq, drop_qpos),
            ("qvel", model.nv, drop_qvel),
            ("ctrl", model.nu, drop_ctrl),
            ("act", model.na, drop_act),
        ):
            values = np.asarray(getattr(key, attr), dtype=float)
            if len(drop) and values.size == size and size > 0:
                setattr(key, attr, np.delete(values, list(drop)).tolist())


def _delete_sensors(spec: mujoco.MjSpec, objtype: mujoco.mjtObj, names: set[str]) -> None:
    for sensor in list(spec.sensors):
        hit = (sensor.objtype == objtype and sensor.objname in names) or (
            sensor.reftype == objtype and sensor.refname in names
        )
        if hit:
            logger.info("deleting sensor %r (references removed %s)", sensor.name, objtype.name)
            spec.delete(sensor)


# ------------------------------------------------------------------------ lock_joints


def lock_joints(spec: mujoco.MjSpec, values: dict[str, float]) -> list[str]:
    """Remove hinge/slide joints, welding each body to its parent at the given value.

    A joint whose value equals its reference (``qpos0``, normally 0) is simply deleted,
    wherever it is in its body's joint list. A joint at any other value is folded into the
    body's ``pos``/``quat``, which is exact only if every joint before it in the body is
    locked too (MuJoCo composes a body's joints in order); otherwise ``ValueError``.

    Joints driven by a locked joint through an active ``<equality><joint>`` are locked
    too, at their coupled value (transitively). Locking a driven joint whose driver stays
    free is refused (the coupling would also freeze the driver). Equality constraints,
    sensors and joint-transmission actuators that refer to removed joints are deleted;
    keyframes lose the removed ``qpos``/``qvel`` (and ``ctrl``/``act``) entries.

    Args:
        spec: Spec to edit in place; it must compile.
        values: Joint name -> value (rad for hinges, m for slides).

    Returns:
        Names of all removed joints (requested and coupled), in model order.

    Raises:
        KeyError: A name is not a joint.
        ValueError: A joint is not hinge/slide; a nonzero joint follows a free one in its
            body; a driven joint would be locked without its driver; a requested value
            contradicts a coupling; a fixed tendon uses a removed joint.
    """
    model = spec.compile()
    locked: dict[int, float] = {}
    for name, value in values.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise KeyError(f"lock_joints: no joint named {name!r}")
        if int(model.jnt_type[jid]) not in _HINGE_SLIDE:
            raise ValueError(f"lock_joints: joint {name!r} is not a hinge or slide joint")
        locked[jid] = float(value)

    # Propagate through joint couplings (driver locked -> driven locked at coupled value).
    couplings = _joint_couplings(model)
    changed = True
    while changed:
        changed = False
        for driven, driver, coef in couplings:
            if driver < 0 or driver not in locked:
                continue
            value = _coupled_value(model, driven, driver, coef, locked[driver])
            if driven in locked:
                if abs(locked[driven] - value) > _COUPLING_TOL * max(1.0, abs(value)):
                    raise ValueError(
                        f"lock_joints: joint {_name(model, mujoco.mjtObj.mjOBJ_JOINT, driven)!r}"
                        f" requested at {locked[driven]} but its coupling to"
                        f" {_name(model, mujoco.mjtObj.mjOBJ_JOINT, driver)!r} gives {value}"
                    )
                continue
            locked[driven] = value
            changed = True
    for driven, driver, _ in couplings:
        if driven in locked and driver >= 0 and driver not in locked:
            raise ValueError(
                f"lock_joints: joint {_name(model, mujoco.mjtObj.mjOBJ_JOINT, driven)!r} is"
                " driven by an equality from"
                f" {_name(model, mujoco.mjtObj.mjOBJ_JOINT, driver)!r}; lock that joint instead"
            )

    names = {jid: _name(model, mujoco.mjtObj.mjOBJ_JOINT, jid) for jid in locked}
    removed_names = {names[j] for j in locked}

    # Fixed tendons cannot lose a joint term through the spec API: refuse.
    for tendon in spec.tendons:
        for wrap in tendon.path:
            if wrap.type == mujoco.mjtWrap.mjWRAP_JOINT and wrap.target.name in removed_names:
                raise ValueError(
                    f"lock_joints: fixed tendon {tendon.name!r} uses joint {wrap.target.name!r}"
                )

    # Plan the folds, body by body, before touching the spec.
    folds: list[tuple[mujoco.MjsBody, np.ndarray, np.ndarray]] = []
    for bid in sorted({int(model.jnt_bodyid[j]) for j in locked}):
        adr, num = model.body_jntadr[bid], model.body_jntnum[bid]
        body = spec.body(_name(model, mujoco.mjtObj.mjOBJ_BODY, bid))
        if body is None:
            raise ValueError(f"lock_joints: body {bid} has no name; cannot edit it")
        pos = np.array(body.pos, dtype=float)
        quat = _body_local_quat(spec, body)
        prefix_locked, folded = True, False
        for jid in range(adr, adr + num):
            if jid not in locked:
                prefix_locked = False
                continue
            displacement = locked[jid] - model.qpos0[model.jnt_qposadr[jid]]
            if abs(displacement) <= _ZERO_DISPLACEMENT:
                continue
            if not prefix_locked:
                raise ValueError(
                    f"lock_joints: joint {names[jid]!r} is locked at {locked[jid]} (not its"
                    " reference) but is not the first joint of its body and the joints before"
                    " it stay free; lock it at its reference or lock the earlier joints too"
                )
            pos, quat = _fold_joint(
                pos,
                quat,
                model.jnt_type[jid],
                model.jnt_pos[jid],
                model.jnt_axis[jid],
                displacement,
            )
            folded = True
        if folded:
            folds.append((body, pos, quat))

    # Edit the spec.
    for body, pos, quat in folds:
        body.pos = pos.tolist()
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        body.quat = quat.tolist()
    for eq in list(spec.equalities):
        if eq.type == mujoco.mjtEq.mjEQ_JOINT and (
            eq.name1 in removed_names or eq.name2 in removed_names
        ):
            spec.delete(eq)
    drop_ctrl, drop_act, dropped_actuators = [], [], set()
    for aid in range(model.nu):
        trn = int(model.actuator_trntype[aid])
        if trn in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)) and (
            int(model.actuator_trnid[aid, 0]) in locked
        ):
            aname = _name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, aid)
            logger.warning("lock_joints: deleting actuator %r of a locked joint", aname)
            spec.delete(spec.actuator(aname))
            dropped_actuators.add(aname)
            drop_ctrl.append(aid)
            adr = model.actuator_actadr[aid]
            if adr >= 0:
                drop_act.extend(range(adr, adr + model.actuator_actnum[aid]))
    _delete_sensors(spec, mujoco.mjtObj.mjOBJ_JOINT, removed_names)
    _delete_sensors(spec, mujoco.mjtObj.mjOBJ_ACTUATOR, dropped_actuators)
    drop_qpos = [model.jnt_qposadr[j] for j in locked]
    drop_qvel = [model.jnt_dofadr[j] for j in locked]
    _rewrite_keys(
        spec,
        model,
        drop_qpos=drop_qpos,
        drop_qvel=drop_qvel,
        drop_ctrl=drop_ctrl,
        drop_act=drop_act,
    )
    for jid in locked:
        spec.delete(spec.joint(names[jid]))
    ordered = [names[j] for j in sorted(locked)]
    logger.info("lock_joints: removed %d joints: %s", len(ordered), ", ".join(ordered))
    return ordered


# --------------------------------------------------------------------- remove_muscles


def _geom_has_mass(spec: mujoco.MjSpec, geom: mujoco.MjsGeom) -> bool:
    if not np.isnan(geom.mass):
        return geom.mass > 0
    if geom.density <= 0:
        return False
    mode = spec.compiler.inertiafromgeom
    if mode == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE:
        return True
    if mode == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE:
        return False
    parent = geom.parent
    return not getattr(parent, "explicitinertial", False)


def _path_elements(tendon: mujoco.MjsTendon) -> Iterable[mujoco.MjsSite | mujoco.MjsGeom]:
    for wrap in tendon.path:
        if wrap.type in (
            mujoco.mjtWrap.mjWRAP_SITE,
            mujoco.mjtWrap.mjWRAP_SPHERE,
            mujoco.mjtWrap.mjWRAP_CYLINDER,
        ):
            yield wrap.target
        side = wrap.sidesite
        if side is not None:
            yield side


def remove_muscles(spec: mujoco.MjSpec, names: Iterable[str]) -> None:
    """Delete muscle actuators, their tendons and the path points only they used.

    A tendon is deleted with its actuator unless another actuator still pulls on it.
    Sites and wrap geoms on a deleted tendon's path are deleted when no remaining tendon,
    actuator, sensor or equality refers to them; a geom that collides
    (``contype``/``conaffinity`` nonzero) or contributes mass is always kept. Sensors on
    deleted actuators/tendons are deleted; keyframes lose the ``ctrl``/``act`` entries.

    Args:
        spec: Spec to edit in place; it must compile.
        names: Actuator names.

    Raises:
        KeyError: A name is not an actuator.
    """
    names = list(dict.fromkeys(names))
    if not names:
        return
    model = spec.compile()
    by_name = {a.name: a for a in spec.actuators}
    missing = [n for n in names if n not in by_name]
    if missing:
        raise KeyError(f"remove_muscles: no actuators named {missing}")
    doomed = set(names)

    drop_ctrl, drop_act = [], []
    for name in names:
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        drop_ctrl.append(aid)
        adr = model.actuator_actadr[aid]
        if adr >= 0:
            drop_act.extend(range(adr, adr + model.actuator_actnum[aid]))

    still_pulled = {
        a.target
        for a in spec.actuators
        if a.name not in doomed and a.trntype == mujoco.mjtTrn.mjTRN_TENDON
    }
    tendons = {t.name: t for t in spec.tendons}
    doomed_tendons = [
        tendons[by_name[n].target]
        for n in names
        if by_name[n].trntype == mujoco.mjtTrn.mjTRN_TENDON
        and by_name[n].target in tendons
        and by_name[n].target not in still_pulled
    ]
    doomed_tendon_names = {t.name for t in doomed_tendons}

    # Path elements of deleted tendons, minus everything still referenced elsewhere.
    candidates = {id(e): e for t in doomed_tendons for e in _path_elements(t)}
    used = {
        id(e) for t in spec.tendons if t.name not in doomed_tendon_names for e in _path_elements(t)
    }
    referenced_names: set[str] = set()
    for a in spec.actuators:
        if a.name not in doomed:
            referenced_names.update((a.target, a.refsite, a.slidersite))
    for s in spec.sensors:
        referenced_names.update((s.objname, s.refname))
    for eq in spec.equalities:
        referenced_names.update((eq.name1, eq.name2))
    referenced_names.discard("")

    for name in names:
        spec.delete(by_name[name])
    _delete_sensors(spec, mujoco.mjtObj.mjOBJ_ACTUATOR, doomed)
    _delete_sensors(spec, mujoco.mjtObj.mjOBJ_TENDON, doomed_tendon_names)
    for eq in list(spec.equalities):
        if eq.type == mujoco.mjtEq.mjEQ_TENDON and (
            eq.name1 in doomed_tendon_names or eq.name2 in doomed_tendon_names
        ):
            spec.delete(eq)
    for tendon in doomed_tendons:
        spec.delete(tendon)

    n_sites = n_geoms = 0
    for key, elem in candidates.items():
        if key in used or (elem.name and elem.name in referenced_names):
            continue
        if isinstance(elem, mujoco.MjsGeom):
            if elem.contype or elem.conaffinity or _geom_has_mass(spec, elem):
                continue
            n_geoms += 1
        else:
            n_sites += 1
        spec.delete(elem)
    _rewrite_keys(spec, model, drop_ctrl=drop_ctrl, drop_act=drop_act)
    logger.info(
        "remove_muscles: removed %d actuators, %d tendons, %d sites, %d wrap geoms",
        len(names),
        len(doomed_tendons),
        n_sites,
        n_geoms,
    )


# ------------------------------------------------------------ moment arms and spans


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
    for qpos in poses:
        _apply_couplings(model, qpos)
    return poses


def _coupling_map(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``T[dof, k] = d q_dof / d q_k`` for free (undriven) dofs ``k`` at ``qpos``.

    Driven hinge/slide dofs get the chain-rule row of their driver; driven dofs' columns
    are zero, so ``J @ T`` is the effective (total) derivative with respect to the
    independent coordinates.
    """
    T = np.eye(model.nv)
    couplings = _joint_couplings(model)
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
    driven = {d for d, _, _ in _joint_couplings(model)}
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


def _dofs_of(model: mujoco.MjModel, joints: Sequence[str], caller: str) -> list[int]:
    dofs = []
    for name in joints:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise KeyError(f"{caller}: no joint named {name!r}")
        dofs.append(int(model.jnt_dofadr[jid]))
    return dofs


def planar_muscles(
    model: mujoco.MjModel,
    sagittal_joints: Sequence[str],
    min_moment_arm_m: float = 0.005,
    n_poses: int = _DEFAULT_POSES,
    seed: int = _DEFAULT_SEED,
    out_of_plane_joints: Sequence[str] | None = None,
    min_ratio: float = 0.5,
) -> list[str]:
    """Muscles that act in the sagittal plane; the rest are out-of-plane.

    A muscle is kept if both:

    * its peak ``|moment arm|`` about the sagittal joints (max over those joints and over
      the poses of :func:`muscle_spans`) is at least ``min_moment_arm_m``;
    * its sagittal moment arm is at least ``min_ratio`` times its out-of-plane one, each
      taken as the largest ``|moment arm|`` over the joint group, averaged over the poses.

    The second test is what discriminates on MyoLeg: over the hip's range nearly every hip
    muscle reaches 5 mm of flexion moment arm somewhere, so the first test alone keeps
    all 80; the ratio drops the ab/adductors, deep rotators and evertors.

    Args:
        model: Compiled model.
        sagittal_joints: Hinge/slide joints of the plane (e.g. hip flexion, knee, ankle).
        min_moment_arm_m: Minimum peak sagittal moment arm (m).
        n_poses: Number of poses including ``qpos0`` (1: ``qpos0`` only).
        seed: Seed of the random poses.
        out_of_plane_joints: Joints for the ratio test. None: every other hinge/slide
            joint not driven by a coupling. Empty: no ratio test.
        min_ratio: Minimum (mean sagittal arm) / (mean out-of-plane arm).

    Returns:
        Names of the kept muscles, in actuator order.

    Raises:
        KeyError: A joint name is unknown.
    """
    dofs = _dofs_of(model, sagittal_joints, "planar_muscles")
    if out_of_plane_joints is None:
        oop = [int(model.jnt_dofadr[j]) for j in _spannable_joints(model)]
        oop = [d for d in oop if d not in set(dofs)]
    else:
        oop = _dofs_of(model, out_of_plane_joints, "planar_muscles")
    ids, arms = muscle_moment_arms(model, n_poses, seed)
    if not ids:
        return []
    peak = np.abs(arms[:, :, dofs]).max(axis=(0, 2))
    keep = peak >= min_moment_arm_m
    if oop:
        sag_mean = np.abs(arms[:, :, dofs]).max(axis=2).mean(axis=0)
        oop_mean = np.abs(arms[:, :, oop]).max(axis=2).mean(axis=0)
        keep &= sag_mean >= min_ratio * oop_mean
    return [
        _name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, aid)
        for aid, k in zip(ids, keep, strict=True)
        if k
    ]


# ------------------------------------------------------------------ restrict_contacts


def restrict_contacts(
    spec: mujoco.MjSpec, keep_geoms: Sequence[str], with_geoms: Sequence[str]
) -> None:
    """Allow contacts only between a geom of ``keep_geoms`` and one of ``with_geoms``.

    Done with the collision bitmasks (no explicit pairs are added): geoms in
    ``keep_geoms`` get ``contype=CONTACT_BIT`` and ``conaffinity=0``, geoms in
    ``with_geoms`` ``contype=0`` and ``conaffinity=CONTACT_BIT`` (a geom in both gets
    both bits), every other geom ``0/0``. So keep-with pairs pass MuJoCo's filter
    (``contype1 & conaffinity2 || contype2 & conaffinity1``) while keep-keep and with-with
    pairs do not. MuJoCo's body filters still apply (no contacts within a body or its welded
    bodies, nor between parent and child unless ``filterparent`` is disabled). Explicit
    ``<pair>``s are deleted unless they join a keep geom with a with geom.

    Args:
        spec: Spec to edit in place.
        keep_geoms: Geom names, e.g. the foot collision geoms.
        with_geoms: Geom names, e.g. the floor and obstacles.

    Raises:
        KeyError: A name is not a geom of the spec.
    """
    keep, other = set(keep_geoms), set(with_geoms)
    geoms = {g.name: g for g in spec.geoms if g.name}
    missing = sorted((keep | other) - set(geoms))
    if missing:
        raise KeyError(f"restrict_contacts: no geoms named {missing}")
    for geom in spec.geoms:
        geom.contype = CONTACT_BIT if geom.name in keep else 0
        geom.conaffinity = CONTACT_BIT if geom.name in other else 0
    for pair in list(spec.pairs):
        a, b = pair.geomname1, pair.geomname2
        if not ((a in keep and b in other) or (b in keep and a in other)):
            spec.delete(pair)


# ------------------------------------------------------------------------- model_size


def contact_pair_mask(model: mujoco.MjModel) -> np.ndarray:
    """``[ngeom, ngeom]`` bool, upper triangle: geom pairs MuJoCo's dynamic filter allows.

    Follows ``mj_collision``: ``contype``/``conaffinity`` compatible either way; not in
    the same weld body; not parent-child weld bodies (unless either is the world, or
    ``filterparent`` is disabled); body pair not ``<exclude>``d; a collision function
    exists for the two geom types (not plane/hfield with plane/hfield); not also an
    explicit ``<pair>`` (counted once, as the pair). Bounding-volume (distance) tests are
    ignored: this is what *can* collide, not what touches now.
    """
    ng = model.ngeom
    if ng < 2 or model.opt.disableflags & (
        mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    ):
        return np.zeros((ng, ng), dtype=bool)
    ct, ca = model.geom_contype, model.geom_conaffinity
    mask = ((ct[:, None] & ca[None, :]) | (ct[None, :] & ca[:, None])) != 0
    body = model.geom_bodyid
    weld = model.body_weldid[body]
    weld_parent = model.body_weldid[model.body_parentid[weld]]
    mask &= weld[:, None] != weld[None, :]
    if not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        nonworld = (weld[:, None] != 0) & (weld[None, :] != 0)
        related = (weld[:, None] == weld_parent[None, :]) | (weld_parent[:, None] == weld[None, :])
        mask &= ~(nonworld & related)
    if model.nexclude:
        excluded = np.zeros((model.nbody, model.nbody), dtype=bool)
        sig = model.exclude_signature.astype(np.int64)
        b1, b2 = sig >> 16, sig & 0xFFFF
        excluded[b1, b2] = excluded[b2, b1] = True
        mask &= ~excluded[body[:, None], body[None, :]]
    flat = (model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE) | (
        model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD
    )
    mask &= ~(flat[:, None] & flat[None, :])
    if model.npair:
        mask[model.pair_geom1, model.pair_geom2] = False
        mask[model.pair_geom2, model.pair_geom1] = False
    return np.triu(mask, k=1)


def model_size(model: mujoco.MjModel) -> dict[str, int]:
    """Size of a compiled model.

    Returns:
        ``dofs`` (``nv``), ``qpos`` (``nq``), ``joints``, ``bodies`` (``nbody``, the world
        included), ``actuators``, ``muscles`` (actuators with muscle dynamics/gain/bias),
        ``tendons``, ``wrap_objects`` (distinct geoms used as tendon wrap objects),
        ``geoms``, ``sites``, ``equalities``, ``contact_pairs`` (geom pairs MuJoCo's
        collision filter lets through, see :func:`contact_pair_mask`, plus explicit pairs).
    """
    wrap_geoms = model.wrap_objid[
        (model.wrap_type == mujoco.mjtWrap.mjWRAP_SPHERE)
        | (model.wrap_type == mujoco.mjtWrap.mjWRAP_CYLINDER)
    ]
    contact_off = model.opt.disableflags & (
        mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    )
    return {
        "dofs": int(model.nv),
        "qpos": int(model.nq),
        "joints": int(model.njnt),
        "bodies": int(model.nbody),
        "actuators": int(model.nu),
        "muscles": len(muscle_ids(model)),
        "tendons": int(model.ntendon),
        "wrap_objects": len(np.unique(wrap_geoms)),
        "geoms": int(model.ngeom),
        "sites": int(model.nsite),
        "equalities": int(model.neq),
        "contact_pairs": int(contact_pair_mask(model).sum())
        + (0 if contact_off else int(model.npair)),
    }
