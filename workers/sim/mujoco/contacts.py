"""Contacts of a MuJoCo model: restrict a spec's collisions, count what can collide.

:func:`restrict_contacts` edits a ``mujoco.MjSpec``; :func:`contact_pair_mask` and
:func:`model_size` take a compiled ``mujoco.MjModel``.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from gaitforge.workers.sim.mujoco.moment_arms import muscle_ids

CONTACT_BIT = 2
"""Bit used by :func:`restrict_contacts`: kept geoms get ``contype=CONTACT_BIT,
conaffinity=0``, their partners ``contype=0, conaffinity=CONTACT_BIT``. A geom added
afterwards collides with the kept geoms only if its ``conaffinity`` has this bit."""


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
