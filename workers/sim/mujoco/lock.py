"""Lock joints of a ``mujoco.MjSpec``: weld each body to its parent at a given value.

Works on any spec (MyoSuite MJCF or one built from our neutral bodies) and keeps it
compilable: equality constraints, sensors, keyframe entries and joint actuators that refer
to removed joints are removed or rewritten with them. Also the shared spec-editing
helpers of :mod:`workers.sim.mujoco.removal` (names, keyframe rewriting, sensor deletion)
and the joint couplings (:func:`coupled_qpos`).

Units are MuJoCo's: lengths in metres, hinge angles in radians (joint values are ``qpos``
values, whatever the spec's ``compiler angle``).

Joint couplings: MuJoCo's ``<equality><joint joint1=A joint2=B polycoef=c>`` enforces
``qA - qA0 = sum_k c_k (qB - qB0)^k`` with ``q0`` = ``qpos0`` (the joint ``ref``). A is
the *driven* joint, B the *driver*. MyoLeg drives its knee translations/rotations and
patella joints from ``knee_angle_*`` this way.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import mujoco
import numpy as np

logger = logging.getLogger(__name__)

_HINGE_SLIDE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_ZERO_DISPLACEMENT = 1e-12
_COUPLING_TOL = 1e-6


# --------------------------------------------------------------------------- helpers


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, idx: int) -> str:
    return mujoco.mj_id2name(model, obj, idx) or ""


def joint_couplings(
    model: mujoco.MjModel, name_prefix: str = ""
) -> list[tuple[int, int, np.ndarray]]:
    """Active joint couplings as ``(driven joint, driver joint or -1, polycoef[5])``: every
    ``<equality><joint>`` whose name starts with ``name_prefix`` (all of them by default)."""
    return [
        (int(model.eq_obj1id[i]), int(model.eq_obj2id[i]), model.eq_data[i, :5].copy())
        for i in range(model.neq)
        if model.eq_type[i] == mujoco.mjtEq.mjEQ_JOINT
        and model.eq_active0[i]
        and _name(model, mujoco.mjtObj.mjOBJ_EQUALITY, i).startswith(name_prefix)
    ]


def _coupled_value(
    model: mujoco.MjModel, driven: int, driver: int, coef: np.ndarray, driver_value: float
) -> float:
    q10 = model.qpos0[model.jnt_qposadr[driven]]
    if driver < 0:
        return float(q10 + coef[0])
    x = driver_value - model.qpos0[model.jnt_qposadr[driver]]
    return float(q10 + np.polyval(coef[::-1], x))


def coupled_qpos(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``qpos`` with every joint driven by an active ``<equality><joint>`` set to its value.

    MuJoCo's joint coupling is ``q1 - q1_0 = sum_k c_k (q2 - q2_0)^k`` (``q_0`` = ``qpos0``,
    ``c`` = ``polycoef``); a coupling with no ``joint2`` fixes ``q1 = q1_0 + c_0``.
    Chains (a driver that is itself driven) are resolved.

    Args:
        model: Compiled model.
        qpos: Generalised positions (rad, m), not modified.

    Returns:
        A copy of ``qpos`` that satisfies the joint couplings.
    """
    out = np.array(qpos, dtype=float, copy=True)
    couplings = joint_couplings(model)
    for _ in range(max(1, len(couplings))):  # a chain of n couplings settles in n passes
        before = out.copy()
        for driven, driver, coef in couplings:
            drv = out[model.jnt_qposadr[driver]] if driver >= 0 else 0.0
            out[model.jnt_qposadr[driven]] = _coupled_value(model, driven, driver, coef, drv)
        if np.array_equal(out, before):
            break
    return out


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
    couplings = joint_couplings(model)
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
