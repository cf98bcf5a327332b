"""Import an OpenSim model (``.osim``) as a neutral body, with a report of what was imported,
approximated and dropped.

The model is read through OpenSim's own loader (``opensim.Model``), so every format version
OpenSim reads is read here: an older one (OpenSim 3's ``Version="30000"``, whose tags such as
``HuntCrossleyForce::ContactParametersSet`` no strict XML parser takes) is upgraded by OpenSim
as it loads, and the report says so. The file is checked as XML too, so that a file OpenSim
cannot load either fails with the XML parser's own reason, line and column (``no element
found``: truncated). What maps to the body:

* bodies -> segments (mass, centre of mass, inertia with its products). Each segment's frame
  is its joint's child frame: where OpenSim's child offset frame is not the body frame, the
  segment's centre of mass, inertia, path points, wraps and markers are re-expressed in it;
* joints -> joints with their parent offset frame (location and orientation). Pin, slider,
  universal, gimbal, planar, free, ball (as three hinges) and weld joints, and custom joints:
  each transform axis is a dof; an axis driven by its coordinate through the identity (or its
  negative) is that coordinate's free dof, any other function makes a coupled dof named
  ``<joint>_<axis>``; constant axes are folded into the joint frame where they act first,
  else kept as dofs coupled with a zero slope;
* coordinate couplers -> the dependent coordinate's axes become coupled dofs of the
  independent one (linear couplers compose exactly; others are resampled as a spline);
* coordinates -> ranges, defaults, ``clamped`` as an enforced range; a locked coordinate is
  listed for scenes to lock (the body has no locked flag);
* muscles (Thelen 2003, Millard 2012 equilibrium; any other ``Muscle`` by its Hill
  parameters) -> forces, fibre and tendon lengths, pennation, velocities, time constants and
  the strains of their passive and tendon curves; path points fixed, conditional and moving;
* wrap objects -> cylinders, spheres and ellipsoids on one path segment (a wrap acts between
  two points): within OpenSim's wrap range, the segment OpenSim itself wraps over it on most
  poses of the muscle's coordinate sweeps, or where it never wraps, the segment passing
  closest to the wrap in the default pose; tori are dropped;
* contact spheres and markers as they are. A model without foot contact gets the rule of
  :func:`default_foot_contacts`, which a contacts file overrides.

Anything else (other forces, constraints, controllers, probes) is listed as dropped, with its
path in the model; a component OpenSim does not know, or a malformed file, is refused.
"""

from __future__ import annotations

import logging
import re
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from gaitforge.workers.bodies.osim_basics import (
    Frame,
    ImportContext,
    ImportReport,
    UnsupportedPart,
    as_tuple,
    items,
    read_coordinates,
    vec3_array,
)
from gaitforge.workers.bodies.osim_joints import child_frames, read_joints, read_segment
from gaitforge.workers.bodies.osim_muscles import read_muscles, read_wrap
from gaitforge.workers.bodies.schema import (
    GROUND,
    Body,
    ContactSphere,
    Marker,
    WrapObject,
)
from gaitforge.workers.spec_io import SpecError
from pydantic import TypeAdapter, ValidationError

logger = logging.getLogger(__name__)

OPENSIM_4_DOCUMENT = 40000
"""the first ``OpenSimDocument`` version of OpenSim 4's format"""

FOOT_SPHERE_RADIUS = 0.05
"""m: radius of the default foot contact spheres (the 2017 challenge model's)."""
FOOT_SPHERES = {
    # segment stem: (sphere name, location in OpenSim's body frame for the right side, m)
    "calcn": [("heel", (0.03, 0.04, 0.0))],
    "toes": [("toe_lateral", (0.03, 0.04, 0.03)), ("toe_medial", (0.03, 0.04, -0.03))],
}
"""The default rule: the 2017 challenge model's heel and toe spheres, the toe split in two
across the foot so that a 3-D foot stands on three points (Z is to the right: a left toe's
lateral sphere is at -Z)."""


@dataclass
class ImportResult:
    body: Body
    report: ImportReport


def default_foot_contacts(segments: list[str], frames: dict[str, Frame]) -> list[ContactSphere]:
    """The rule for a model without foot contact (:data:`FOOT_SPHERES`): on each
    ``calcn_r``/``calcn_l`` a heel sphere, on each ``toes_r``/``toes_l`` a lateral and a
    medial toe sphere, of radius :data:`FOOT_SPHERE_RADIUS`; none when the model lacks those
    segments."""
    spheres = []
    for side, mirror in (("r", 1.0), ("l", -1.0)):
        for stem, placed in FOOT_SPHERES.items():
            segment = f"{stem}_{side}"
            if segment not in segments:
                continue
            for label, (x, y, z) in placed:
                location = frames[segment].point_in(np.array([x, y, mirror * z]))
                spheres.append(
                    ContactSphere(
                        name=f"{side}_{label}",
                        segment=segment,
                        location=as_tuple(location),
                        radius=FOOT_SPHERE_RADIUS,
                    )
                )
    return spheres


def _model_contacts(ctx: ImportContext) -> list[ContactSphere]:
    import opensim

    spheres = []
    geometry = ctx.model.getContactGeometrySet()
    for g in items(geometry):
        where = g.getAbsolutePathString()
        sphere = opensim.ContactSphere.safeDownCast(g)
        if sphere is None:
            ctx.report.dropped.append(f"{where}: contact {g.getConcreteClassName()}")
            continue
        segment, location = ctx.in_segment(sphere.getFrame(), vec3_array(sphere.get_location()))
        if segment == GROUND:
            continue
        foot = any(k in segment for k in ("calcn", "toes", "foot"))
        name = sphere.getName()
        side = "_r" if segment.endswith("_r") else "_l" if segment.endswith("_l") else ""
        if foot and side and not (name.endswith(side) or name.startswith(side[1] + "_")):
            name = f"{name}{side}"
        spheres.append(
            ContactSphere(
                name=name,
                segment=segment,
                location=as_tuple(location),
                radius=sphere.getRadius(),
                part="foot" if foot else "body",
            )
        )
    return spheres


def _load_contacts(path: Path) -> list[ContactSphere]:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SpecError(f"{path}: not a readable contacts file ({exc})") from None
    try:
        return TypeAdapter(list[ContactSphere]).validate_python(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise SpecError(
            f"{path}: {where}: {first['msg']} (a list of contact spheres: name, segment, "
            "location, radius, part)"
        ) from None


# ---- the file ----------------------------------------------------------------------------


def read_model_file(path: Path) -> tuple[str, str | None]:
    """The file's text, and why a strict XML parser refuses it (its reason, line and column;
    None where it does not). A file that parses but is not an OpenSim model raises.

    Raises:
        SpecError: the file is missing or unreadable, or its XML is no OpenSim document.
    """
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(
            f"{path}: cannot read the model ({exc.__class__.__name__}: {exc})"
        ) from None
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, column = exc.position
        reason = str(exc).split(":")[0]
        at_end = line >= len(text.splitlines())  # the parser ran out of file
        cause = " (the file ends there: truncated)" if at_end else ""
        return text, f"line {line}, column {column}: not well-formed XML: {reason}{cause}"
    if root.tag != "OpenSimDocument" or root.find("Model") is None:
        raise SpecError(f"{path}: not an OpenSim model (no <OpenSimDocument><Model>); refused")
    return text, None


def _document_version(text: str) -> int | None:
    """The ``OpenSimDocument``'s ``Version`` (30000: OpenSim 3.0), None if it names none."""
    match = re.search(r"<OpenSimDocument\s+Version=\"(\d+)\"", text)
    return int(match.group(1)) if match else None


def _unknown_components(text: str) -> list[str]:
    """Named XML elements whose type OpenSim does not know (its loader refuses them)."""
    import opensim

    unknown = []
    for match in re.finditer(r"<([A-Za-z_][\w.]*)\s+name=\"([^\"]*)\"", text):
        tag, name = match.group(1), match.group(2)
        if opensim.OpenSimObject.getDefaultInstanceOfType(tag) is None:
            line = text.count("\n", 0, match.start()) + 1
            unknown.append(f'line {line}: <{tag} name="{name}">: an unknown component')
    return unknown


def _load_model(path: Path, text: str, xml_problem: str | None) -> tuple[Any, Any]:
    """The model and its initial state; where OpenSim refuses the file, the XML parser's
    problem with it (``xml_problem``), else the first component it does not know (line, tag,
    name), else OpenSim's own first line, as a ``SpecError``."""
    import opensim

    opensim.Logger.removeFileSink()
    opensim.Logger.setLevelString("off")
    try:
        model = opensim.Model(str(path))
        state = model.initSystem()
    except RuntimeError as exc:
        if xml_problem is not None:
            raise SpecError(f"{path}: {xml_problem}; OpenSim cannot load it; refused") from None
        unknown = _unknown_components(text)
        if unknown:
            more = f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else ""
            problem = f"{unknown[0]}{more}; OpenSim cannot load it; refused"
            raise SpecError(f"{path}: {problem}") from None
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else "no message"
        raise SpecError(f"{path}: OpenSim cannot load the model: {message}; refused") from None
    return model, state


def import_osim(
    path: Path | str, *, contacts: Path | str | None = None, name: str | None = None
) -> ImportResult:
    """Import the OpenSim model at ``path`` as a neutral body.

    Args:
        contacts: a YAML list of contact spheres that replaces the model's own and the
            default rule's (:func:`default_foot_contacts`).
        name: the body's name (default: the file's stem).

    Raises:
        SpecError: one line naming the file and the element (its path in the model) that
            could not be imported, and what was done (refused).
    """
    started = time.perf_counter()
    path = Path(path)
    text, xml_problem = read_model_file(path)
    model, state = _load_model(path, text, xml_problem)
    report = ImportReport(model=path.name)
    version = _document_version(text)
    if version is not None and version < OPENSIM_4_DOCUMENT:
        report.notes.append(
            f"the file is OpenSim document version {version} (before OpenSim 4); OpenSim "
            "upgraded it as it loaded"
            + ("" if xml_problem is None else f" (a strict XML parser refuses it: {xml_problem})")
        )
    try:
        body = _import(model, state, report, name or path.stem, contacts)
    except UnsupportedPart as exc:
        raise SpecError(f"{path}: {exc}; refused") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        raise SpecError(
            f"{path}: the imported body is not valid: {'.'.join(map(str, first['loc']))}: "
            f"{first['msg']}; refused"
        ) from None
    report.seconds = time.perf_counter() - started
    logger.info("imported %s in %.2f s", path, report.seconds)
    return ImportResult(body=body, report=report)


def _import(
    model: Any, state: Any, report: ImportReport, name: str, contacts: Path | str | None
) -> Body:
    ctx = ImportContext(model, state, read_coordinates(model, report), child_frames(model), report)
    bodies = list(items(model.getBodySet()))
    segments = [read_segment(b, ctx.frames[b.getName()], report) for b in bodies]
    joints = read_joints(ctx)
    wraps: dict[str, WrapObject] = {}
    used: set[str] = set()
    for body in bodies:
        for obj in items(body.getWrapObjectSet()):
            wrap = read_wrap(obj, body.getName(), ctx, used)
            if wrap is not None:
                wraps[obj.getName()] = wrap
    muscles = read_muscles(ctx, wraps)
    for what, components in (
        ("controller", model.getControllerSet()),
        ("probe", model.getProbeSet()),
        ("component", model.getMiscModelComponentSet()),
    ):
        for component in items(components):
            report.dropped.append(
                f"{component.getAbsolutePathString()}: {component.getConcreteClassName()} "
                f"(a {what}; not imported)"
            )
    used_wraps = {w for m in muscles for w in m.wraps}
    markers = _markers(ctx)
    spheres = _contacts(ctx, [s.name for s in segments], contacts)
    for coordinate in ctx.coords.info.values():
        if coordinate.get_locked():
            report.notes.append(
                f"coordinate {coordinate.getName()!r} is locked in the model at "
                f"{coordinate.getDefaultValue():g}: scenes lock it with keep.lock_at"
            )
    body = Body(
        name=name,
        description=f"imported from {report.model} by gaitforge bodies import",
        source=_credits(model),
        segments=segments,
        joints=joints,
        muscles=muscles,
        wrap_objects=[w for w in wraps.values() if w.name in used_wraps],
        contact_spheres=spheres,
        markers=markers,
    )
    report.counts = {
        "segments": len(body.segments),
        "joints": len(body.joints),
        "free dofs": len(body.dof_names) - len(body.coupled_dofs),
        "coupled dofs": len(body.coupled_dofs),
        "muscles": len(body.muscles),
        "path points": sum(len(m.points) for m in body.muscles),
        "conditional path points": sum(
            1 for m in body.muscles for p in m.points if p.active_when is not None
        ),
        "moving path points": sum(
            1 for m in body.muscles for p in m.points if p.moves_with is not None
        ),
        "fitted stand-ins": sum(1 for m in body.muscles for p in m.points if p.stand_in),
        "wrap objects": len(body.wrap_objects),
        "contact spheres": len(body.contact_spheres),
        "markers": len(body.markers),
    }
    return body


def _markers(ctx: ImportContext) -> list[Marker]:
    markers = []
    marker_set = ctx.model.getMarkerSet()
    for marker in items(marker_set):
        segment, location = ctx.in_segment(
            marker.getParentFrame(), vec3_array(marker.get_location())
        )
        if segment != GROUND:
            markers.append(
                Marker(name=marker.getName(), segment=segment, location=as_tuple(location))
            )
    return markers


def _contacts(
    ctx: ImportContext, segments: list[str], contacts: Path | str | None
) -> list[ContactSphere]:
    if contacts is not None:
        spheres = _load_contacts(Path(contacts))
        ctx.report.notes.append(f"contact spheres from {Path(contacts).name} ({len(spheres)})")
        return spheres
    spheres = _model_contacts(ctx)
    if any(s.part == "foot" for s in spheres):
        return spheres
    default = default_foot_contacts(segments, ctx.frames)
    if default:
        ctx.report.notes.append(
            f"the model has no foot contact: {len(default)} spheres of radius "
            f"{FOOT_SPHERE_RADIUS} m on {sorted({s.segment for s in default})}, a heel and two "
            "toes a foot (the default rule; --contacts FILE replaces it)"
        )
    else:
        ctx.report.notes.append(
            "the model has no foot contact and no calcn_*/toes_* segments: no contact spheres "
            "(give them with --contacts FILE)"
        )
    return spheres + default


def _credits(model: Any) -> str:
    parts = [model.get_credits().strip(), model.get_publications().strip()]
    return " ".join(p for p in parts if p and p != "Unassigned")[:2000]
