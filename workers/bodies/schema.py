"""Simulator-independent description of a musculoskeletal body.

Conventions (the same as OpenSim's, so a transcription stays literal):
* world frame is Y-up, X forward, Z to the body's right; gravity is -Y;
* lengths in metres, masses in kilograms, angles in radians, forces in newtons;
* every location is expressed in the frame of the segment it names.

A body is a tree of segments. Each non-root segment hangs from its parent through one
:class:`Joint`, whose degrees of freedom (:class:`Dof`) are applied in the order listed,
each about or along an axis expressed in the joint frame (the frame left by the dofs before
it). The joint frame sits at ``location_in_parent``, turned by ``orientation_in_parent``; the
child segment's frame is the joint frame once its dofs have acted. The root segment hangs
from the ground the same way (for ``gait2d`` a planar joint: slide x, slide y, hinge z).

A dof may be ``coupled``: its value is a function of another dof (OpenSim's CustomJoint
axes with spline or linear functions, a coordinate coupler). Path points may be active only
over a dof's range (conditional) or move with a dof (OpenSim's moving path points). A
backend that lacks a feature approximates it and its compile report says so.
"""

from __future__ import annotations

import itertools
from typing import Annotated, Literal

from gaitforge.workers.bodies.functions import Function
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Vec3 = tuple[float, float, float]
Quartic = tuple[float, float, float, float, float]
PositiveFloat = Annotated[float, Field(gt=0)]
GROUND = "ground"


class _Strict(BaseModel):
    """Base for every file-backed model: unknown keys are errors, values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class Segment(_Strict):
    """A rigid body: mass properties in its own frame."""

    name: str
    mass: PositiveFloat = Field(description="kg")
    com: Vec3 = Field(default=(0.0, 0.0, 0.0), description="centre of mass, m, segment frame")
    inertia: tuple[PositiveFloat, PositiveFloat, PositiveFloat] = Field(
        description="moments about the centre of mass along the segment axes, kg m^2 (xx, yy, zz)"
    )
    inertia_products: Vec3 = Field(
        default=(0.0, 0.0, 0.0), description="products of inertia, kg m^2 (xy, xz, yz)"
    )
    length_hint: float = Field(
        default=0.0, ge=0, description="m; drawn as a capsule along -Y for visuals (0: none)"
    )


class JointLimit(_Strict):
    """A passive limit force (OpenSim's CoordinateLimitForce): a stiff spring beyond ``range``.

    MuJoCo has no one-sided spring: its backend enforces ``range`` as a soft joint limit.
    """

    range: tuple[float, float] = Field(
        description="rad or m, where the force starts (the dof's range is not enforced then)"
    )
    stiffness: PositiveFloat = Field(description="N m/rad (or N/m) past the range")
    damping: float = Field(default=0.0, ge=0, description="N m s/rad (or N s/m) past the range")
    transition: float = Field(default=0.17, gt=0, description="rad or m to full stiffness")


class Coupling(_Strict):
    """The dof is not free: its value is ``function(value of coordinate)``."""

    coordinate: str = Field(description="the free dof that drives this one")
    function: Function


class Dof(_Strict):
    """One degree of freedom of a joint."""

    name: str
    type: Literal["hinge", "slide"]
    axis: Vec3 = Field(description="unit axis in the joint frame")
    range: tuple[float, float] = Field(description="rad for hinge, m for slide")
    default: float = 0.0
    limited: bool = Field(default=True, description="enforce the range with a joint limit")
    limit: JointLimit | None = Field(default=None, description="passive limit force, if any")
    coupled: Coupling | None = Field(
        default=None, description="a function of another dof; such a dof is never an action"
    )

    @model_validator(mode="after")
    def _check(self) -> Dof:
        lo, hi = self.range
        if not lo < hi:
            raise ValueError(f"range must be increasing, got {self.range}")
        if not lo <= self.default <= hi:
            raise ValueError(f"default {self.default} outside range {self.range}")
        if self.limit is not None and not self.limit.range[0] < self.limit.range[1]:
            raise ValueError(f"limit.range must be increasing, got {self.limit.range}")
        if sum(a * a for a in self.axis) < 1e-12:
            raise ValueError("axis must be non-zero")
        return self


class Joint(_Strict):
    """Connects ``child`` to ``parent``; no dofs means a weld."""

    name: str
    parent: str = Field(description=f"segment name or '{GROUND}'")
    child: str
    location_in_parent: Vec3 = (0.0, 0.0, 0.0)
    orientation_in_parent: Vec3 = Field(
        default=(0.0, 0.0, 0.0),
        description="rad, body-fixed X-Y-Z Euler angles of the joint frame (OpenSim's)",
    )
    dofs: list[Dof] = Field(default_factory=list)


class ActiveRange(_Strict):
    """A conditional path point is part of the path only while ``coordinate`` is in ``range``."""

    coordinate: str
    range: tuple[float, float] = Field(description="rad or m")


class MovingLocation(_Strict):
    """A path point whose location (segment frame, m) is a function of ``coordinate``."""

    coordinate: str
    x: Function
    y: Function
    z: Function


class StandIn(_Strict):
    """How a backend without conditional or moving points stands in for such a point: a
    fixed point (on ``segment`` at ``location``, each defaulting to the point's own), none
    (``keep: false``), wrapping over the wrap object ``wrap`` instead, or (a moving point
    only) a carrier that follows the point's path (``follow``). The import picks it to keep
    the muscle's moment arms."""

    keep: bool = True
    segment: str | None = None
    location: Vec3 | None = None
    wrap: str | None = Field(default=None, description="a wrap object in the point's place")
    follow: tuple[Quartic, Quartic, Quartic] | None = Field(
        default=None,
        description="a moving point only: MuJoCo carries it on a light body whose slides keep "
        "it at (x, y, z) = these quartics of its coordinate's value (a0..a4, lowest order "
        "first; m, segment frame), which the import fits to keep the moment arm "
        "(workers/bodies/osim_carriers.py)",
    )

    @model_validator(mode="after")
    def _check(self) -> StandIn:
        if self.follow and (self.segment or self.location or self.wrap or not self.keep):
            raise ValueError(
                "follow: the point is carried along its own path (no segment, location or "
                "wrap, and kept)"
            )
        return self


class PathPoint(_Strict):
    """A via point of a muscle path: fixed, conditional or moving."""

    segment: str
    location: Vec3 = Field(description="m, segment frame; a moving point's at its dof's default")
    active_when: ActiveRange | None = None
    moves_with: MovingLocation | None = None
    stand_in: StandIn | None = Field(
        default=None,
        description="a conditional or moving point's fixed stand-in where a backend has neither "
        "(none: a conditional point is kept iff active at its dof's default; a moving one is "
        "fixed at location)",
    )

    @model_validator(mode="after")
    def _check(self) -> PathPoint:
        if self.stand_in and self.stand_in.follow and self.moves_with is None:
            raise ValueError("stand_in.follow: only a moving point (moves_with) can be followed")
        return self


class WrapRef(_Strict):
    """The muscle path wraps over the named wrap object between its neighbouring points."""

    wrap: str
    use_side: bool = Field(
        default=True,
        description="MuJoCo: keep to the wrap's side point (its sidesite). MuJoCo then forces "
        "the path round that side even where it clears the wrap on the other, which OpenSim's "
        "quadrant does not; the import turns this off where that happens more often than the "
        "path crossing the wrap from the wrong side",
    )


PathElement = PathPoint | WrapRef


class Muscle(_Strict):
    """A Hill-type muscle-tendon unit with a piecewise-straight path."""

    name: str
    max_isometric_force: PositiveFloat = Field(description="N")
    optimal_fiber_length: PositiveFloat = Field(description="m")
    tendon_slack_length: PositiveFloat = Field(description="m")
    pennation_angle: float = Field(default=0.0, ge=0, lt=1.5, description="rad at optimal length")
    max_contraction_velocity: PositiveFloat = Field(
        default=10.0, description="optimal fibre lengths per second"
    )
    passive_fibre_strain: PositiveFloat = Field(
        default=0.6, description="fibre strain at which passive force equals max isometric force"
    )
    passive_shape: PositiveFloat = Field(
        default=4.0,
        description="Thelen 2003 exponential shape of the passive force (KshapePassive)",
    )
    tendon_strain_at_fmax: PositiveFloat = Field(
        default=0.049, description="tendon strain at max isometric force (compliant tendons)"
    )
    activation_time: PositiveFloat = Field(default=0.01, description="s")
    deactivation_time: PositiveFloat = Field(default=0.04, description="s")
    path: list[PathElement] = Field(min_length=2)

    @field_validator("path")
    @classmethod
    def _path_shape(cls, path: list[PathElement]) -> list[PathElement]:
        if not isinstance(path[0], PathPoint) or not isinstance(path[-1], PathPoint):
            raise ValueError("path must start and end with a point")
        for a, b in itertools.pairwise(path):
            if isinstance(a, WrapRef) and isinstance(b, WrapRef):
                raise ValueError("two wrap objects in a row: put a point between them")
        return path

    @property
    def points(self) -> list[PathPoint]:
        return [e for e in self.path if isinstance(e, PathPoint)]

    @property
    def wraps(self) -> list[str]:
        return [e.wrap for e in self.path if isinstance(e, WrapRef)]


class WrapObject(_Strict):
    """A smooth obstacle that muscle paths slide over.

    An ellipsoid's semi-axes are ``radii`` along its frame's axes, its frame turned by
    ``orientation``; ``radius`` is then the sphere a backend without ellipsoids uses.
    """

    name: str
    segment: str
    type: Literal["cylinder", "sphere", "ellipsoid"]
    location: Vec3
    axis: Vec3 = Field(default=(0.0, 0.0, 1.0), description="cylinder axis, segment frame")
    orientation: Vec3 | None = Field(
        default=None, description="rad, X-Y-Z Euler angles of an ellipsoid's frame"
    )
    radii: tuple[PositiveFloat, PositiveFloat, PositiveFloat] | None = Field(
        default=None, description="an ellipsoid's semi-axes, m"
    )
    radius: PositiveFloat
    length: float = Field(default=0.1, gt=0, description="cylinder length, m (visual only)")
    side: Vec3 | None = Field(
        default=None, description="a point (segment frame) on the side the path passes"
    )

    @model_validator(mode="after")
    def _check(self) -> WrapObject:
        if (self.type == "ellipsoid") != (self.radii is not None):
            raise ValueError("radii: given for an ellipsoid, and only for an ellipsoid")
        return self


class ContactSphere(_Strict):
    """A sphere that can touch the ground. ``foot`` spheres carry gait; ``body`` spheres only
    matter in a fall (scenes keep them with ``keep.contacts: all``)."""

    name: str
    segment: str
    location: Vec3
    radius: PositiveFloat
    part: Literal["foot", "body"] = "foot"

    @property
    def foot(self) -> str | None:
        """``foot_right`` or ``foot_left`` for a foot sphere (``r_``/``_r`` names are right)."""
        if self.part != "foot":
            return None
        right = self.name.startswith("r_") or self.name.endswith("_r")
        return "foot_right" if right else "foot_left"


class Marker(_Strict):
    name: str
    segment: str
    location: Vec3


class ContactMaterial(_Strict):
    """Hunt-Crossley style ground contact parameters."""

    stiffness: PositiveFloat = Field(default=1.5e7, description="N/m^(3/2) (Hunt-Crossley)")
    dissipation: float = Field(default=1.0, ge=0, description="s/m")
    static_friction: float = Field(default=0.9, ge=0)
    dynamic_friction: float = Field(default=0.8, ge=0)


class Body(_Strict):
    """A whole musculoskeletal body (see module docstring for conventions)."""

    name: str
    description: str = ""
    source: str = Field(default="", description="where the numbers come from")
    segments: list[Segment]
    joints: list[Joint]
    muscles: list[Muscle] = Field(default_factory=list)
    wrap_objects: list[WrapObject] = Field(default_factory=list)
    contact_spheres: list[ContactSphere] = Field(default_factory=list)
    contact: ContactMaterial = ContactMaterial()
    markers: list[Marker] = Field(default_factory=list)
    planar: bool = Field(default=False, description="all motion in the X-Y plane")

    @model_validator(mode="after")
    def _check_references(self) -> Body:
        seg_names = _unique("segments", [s.name for s in self.segments])
        _unique("joints", [j.name for j in self.joints])
        _unique("dofs", [d.name for j in self.joints for d in j.dofs])
        _unique("muscles", [m.name for m in self.muscles])
        wrap_names = _unique("wrap_objects", [w.name for w in self.wrap_objects])
        children = [j.child for j in self.joints]
        _unique("joint children", children)
        for j in self.joints:
            if j.parent != GROUND and j.parent not in seg_names:
                raise ValueError(f"joint {j.name!r}: unknown parent segment {j.parent!r}")
            if j.child not in seg_names:
                raise ValueError(f"joint {j.name!r}: unknown child segment {j.child!r}")
        orphans = seg_names - set(children)
        if orphans:
            raise ValueError(f"segments without a joint: {sorted(orphans)}")
        roots = [j for j in self.joints if j.parent == GROUND]
        if len(roots) != 1:
            raise ValueError(f"exactly one joint must hang from '{GROUND}', found {len(roots)}")
        self.ordered_joints()
        self._check_couplings()
        free = {d.name for j in self.joints for d in j.dofs if d.coupled is None}
        for m in self.muscles:
            for p in m.points:
                if p.segment not in seg_names:
                    raise ValueError(f"muscle {m.name!r}: unknown segment {p.segment!r}")
                if p.stand_in and p.stand_in.segment and p.stand_in.segment not in seg_names:
                    raise ValueError(
                        f"muscle {m.name!r}: a stand-in on unknown segment {p.stand_in.segment!r}"
                    )
                if p.stand_in and p.stand_in.wrap and p.stand_in.wrap not in wrap_names:
                    raise ValueError(
                        f"muscle {m.name!r}: a stand-in wraps unknown {p.stand_in.wrap!r}"
                    )
                for depends in (p.active_when, p.moves_with):
                    if depends is not None and depends.coordinate not in free:
                        raise ValueError(
                            f"muscle {m.name!r}: a path point depends on {depends.coordinate!r}, "
                            "which is not a free dof"
                        )
            for w in m.wraps:
                if w not in wrap_names:
                    raise ValueError(f"muscle {m.name!r}: unknown wrap object {w!r}")
        for item in [*self.wrap_objects, *self.contact_spheres, *self.markers]:
            if item.segment not in seg_names:
                raise ValueError(f"{item.name!r}: unknown segment {item.segment!r}")
        return self

    def _check_couplings(self) -> None:
        dofs = {d.name: d for j in self.joints for d in j.dofs}
        for dof in dofs.values():
            if dof.coupled is None:
                continue
            driver = dofs.get(dof.coupled.coordinate)
            if driver is None or driver.coupled is not None or driver is dof:
                raise ValueError(
                    f"dof {dof.name!r}: coupled to {dof.coupled.coordinate!r}, which is not "
                    "another free dof of the body"
                )

    # ---- look-ups used by pruning and backends -------------------------------------

    def segment(self, name: str) -> Segment:
        return next(s for s in self.segments if s.name == name)

    def joint_of(self, segment: str) -> Joint:
        """The joint whose child is ``segment``."""
        return next(j for j in self.joints if j.child == segment)

    def ordered_joints(self) -> list[Joint]:
        """Joints depth-first from the ground, siblings in file order (parents first)."""
        ordered: list[Joint] = []

        def visit(parent: str) -> None:
            for joint in self.joints:
                if joint.parent == parent:
                    ordered.append(joint)
                    visit(joint.child)

        visit(GROUND)
        if len(ordered) != len(self.joints):
            raise ValueError("joint tree is not connected to the ground")
        return ordered

    @property
    def dof_names(self) -> list[str]:
        return [d.name for j in self.ordered_joints() for d in j.dofs]

    @property
    def coupled_dofs(self) -> dict[str, str]:
        """Each coupled dof and the free dof that drives it."""
        return {d.name: d.coupled.coordinate for j in self.joints for d in j.dofs if d.coupled}

    def dof(self, name: str) -> Dof:
        return next(d for j in self.joints for d in j.dofs if d.name == name)

    def joint_of_dof(self, name: str) -> Joint:
        return next(j for j in self.joints if any(d.name == name for d in j.dofs))

    def chain_to_root(self, segment: str) -> list[str]:
        """Segments from ``segment`` up to the root, inclusive."""
        chain = [segment]
        while (parent := self.joint_of(chain[-1]).parent) != GROUND:
            chain.append(parent)
        return chain

    def dofs_spanned(self, muscle: Muscle) -> list[str]:
        """Free dofs on the tree path between the segments a muscle's points attach to (a
        coupled dof counts as the dof that drives it)."""
        segments = {p.segment for p in muscle.points}
        chains = [self.chain_to_root(s) for s in segments]
        common = set.intersection(*(set(c) for c in chains))
        crossed: set[str] = set()
        for chain in chains:
            for seg in chain:
                if seg in common:
                    break
                crossed.add(seg)
        spanned = [
            d.coupled.coordinate if d.coupled else d.name
            for j in self.ordered_joints()
            if j.child in crossed
            for d in j.dofs
        ]
        return list(dict.fromkeys(spanned))

    @property
    def total_mass(self) -> float:
        return sum(s.mass for s in self.segments)


def _unique(what: str, names: list[str]) -> set[str]:
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise ValueError(f"duplicate name {n!r} in {what}")
        seen.add(n)
    return seen
