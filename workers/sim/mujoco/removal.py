"""Remove parts of a MuJoCo spec: muscles (with what only they used), and everything that
neither collides, weighs, nor carries a muscle path (visuals and markers).

Both keep the spec compilable: tendons, path points, sensors and keyframe entries go with
the muscles they belong to.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import mujoco
import numpy as np
from gaitforge.workers.sim.mujoco.lock import _delete_sensors, _rewrite_keys

logger = logging.getLogger(__name__)


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


def _key(elem: mujoco.MjsGeom | mujoco.MjsSite) -> tuple[str, str]:
    """Identity of a path element: its kind and name."""
    return (type(elem).__name__, elem.name)


def _referenced_names(spec: mujoco.MjSpec, skip_actuators: set[str]) -> set[str]:
    """Names that actuators (other than ``skip_actuators``), sensors, equalities and explicit
    contact pairs refer to."""
    names: set[str] = set()
    for a in spec.actuators:
        if a.name not in skip_actuators:
            names.update((a.target, a.refsite, a.slidersite))
    for sensor in spec.sensors:
        names.update((sensor.objname, sensor.refname))
    for eq in spec.equalities:
        names.update((eq.name1, eq.name2))
    for pair in spec.pairs:
        names.update((pair.geomname1, pair.geomname2))
    names.discard("")
    return names


def _is_inert(spec: mujoco.MjSpec, geom: mujoco.MjsGeom) -> bool:
    """Neither collides nor contributes mass: only drawn (or wrapped over)."""
    return not (geom.contype or geom.conaffinity or _geom_has_mass(spec, geom))


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
    # Keyed by name: MJCF path elements are always named, and the Python wrappers that
    # ``tendon.path`` returns are new objects each time (their id() says nothing).
    candidates = {_key(e): e for t in doomed_tendons for e in _path_elements(t)}
    used = {
        _key(e)
        for t in spec.tendons
        if t.name not in doomed_tendon_names
        for e in _path_elements(t)
    }
    referenced_names = _referenced_names(spec, skip_actuators=doomed)

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
            if not _is_inert(spec, elem):
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


def strip_unused(spec: mujoco.MjSpec) -> tuple[int, int]:
    """Delete geoms that neither collide, weigh nor carry a muscle path (bone meshes,
    visual capsules) and sites that no tendon, actuator, sensor or equality uses (markers).

    Run it after contacts are restricted: collision geoms the scene does not use then count
    as inert too. Returns the number of (geoms, sites) deleted.
    """
    on_paths = {_key(e) for t in spec.tendons for e in _path_elements(t)}
    referenced = _referenced_names(spec, skip_actuators=set())

    def unused(elem: mujoco.MjsGeom | mujoco.MjsSite) -> bool:
        return _key(elem) not in on_paths and not (elem.name and elem.name in referenced)

    geoms = [g for g in spec.geoms if unused(g) and _is_inert(spec, g)]
    sites = [site for site in spec.sites if unused(site)]
    for elem in (*geoms, *sites):
        spec.delete(elem)
    logger.info("strip_unused: removed %d geoms and %d sites", len(geoms), len(sites))
    return len(geoms), len(sites)
