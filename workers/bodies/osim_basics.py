"""What the OpenSim import shares: its report, frames and rotations, OpenSim functions as
the body's (:mod:`workers.bodies.functions`), coordinates and their couplers."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.rotations import rotation_xyz

ARM_TOLERANCE_M = 0.002
ARM_TOLERANCE_SHARE = 0.05
"""A converted muscle keeps its moment arm about a coordinate if the RMS error over the
coordinate's range is within 2 mm or 5 % of the peak moment arm (the conversion's measure,
``workers.fidelity.conversion``, and the import's fits)."""


def arm_allowance(reference: np.ndarray) -> float:
    """The RMS moment-arm error (m) allowed against ``reference`` moment arms (m)."""
    return max(ARM_TOLERANCE_M, ARM_TOLERANCE_SHARE * float(np.abs(reference).max()))


@dataclass
class ImportReport:
    """What an import did.

    Attributes:
        model: the file imported.
        counts: how many of each part the body has (segments, dofs, coupled dofs, muscles...).
        approximated: one line per part that changed on the way, naming its path in the model.
        dropped: one line per part left out, naming its path and why.
        notes: what a user should know to use the body (locked coordinates, contacts).
        seconds: wall time of the import.
    """

    model: str
    counts: dict[str, int] = field(default_factory=dict)
    approximated: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_data(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "counts": self.counts,
            "approximated": self.approximated,
            "dropped": self.dropped,
            "notes": self.notes,
            "seconds": round(self.seconds, 3),
        }

    def to_markdown(self) -> str:
        lines = [f"# Import of `{self.model}`", "", f"Imported in {self.seconds:.2f} s.", ""]
        lines += ["| part | count |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in self.counts.items()]
        for title, items in (
            ("Approximated", self.approximated),
            ("Dropped", self.dropped),
            ("Notes", self.notes),
        ):
            lines += ["", f"## {title}", ""]
            lines += [f"- {item}" for item in items] or ["- none"]
        return "\n".join(lines) + "\n"


# ---- small geometry helpers -----------------------------------------------------------


def items(opensim_set: Any) -> Iterator[Any]:
    """The members of an OpenSim set or array (anything with ``getSize`` and ``get``)."""
    return (opensim_set.get(i) for i in range(opensim_set.getSize()))


def joints_between(model: Any, bodies: set[str]) -> list[Any]:
    """The joints of an OpenSim model on the tree paths between ``bodies`` (names of bodies or
    ground): each joint whose child is on one body's path to the root but not on every
    body's, ordered by the child's name."""
    parent_of: dict[str, tuple[str, Any]] = {}
    for joint in items(model.getJointSet()):
        child = joint.getChildFrame().findBaseFrame().getName()
        parent_of[child] = (joint.getParentFrame().findBaseFrame().getName(), joint)

    def chain(body: str) -> list[str]:
        links = [body]
        while links[-1] in parent_of and len(links) <= len(parent_of):
            links.append(parent_of[links[-1]][0])
        return links

    chains = [chain(body) for body in bodies]
    common = set.intersection(*(set(c) for c in chains)) if chains else set()
    crossed = {body for c in chains for body in c if body not in common and body in parent_of}
    return [parent_of[body][1] for body in sorted(crossed)]


def vec3_array(v: Any) -> np.ndarray:
    return np.array([v.get(0), v.get(1), v.get(2)], dtype=float)


def as_tuple(v: np.ndarray) -> tuple[float, float, float]:
    return (clean_float(v[0]), clean_float(v[1]), clean_float(v[2]))


def clean_float(x: float) -> float:
    """Round away float noise (file values are given to at most ~1e-12)."""
    return float(round(float(x), 12)) + 0.0


@dataclass(frozen=True)
class Frame:
    """A rigid transform: ``p`` (m) and ``r`` (3x3) of a frame in its base body's frame."""

    p: np.ndarray
    r: np.ndarray

    @staticmethod
    def identity() -> Frame:
        return Frame(np.zeros(3), np.eye(3))

    def point_in(self, point_in_base: np.ndarray) -> np.ndarray:
        """A point given in the base frame, expressed in this frame."""
        return self.r.T @ (np.asarray(point_in_base) - self.p)

    def rotation_in(self, rotation_in_base: np.ndarray) -> np.ndarray:
        return self.r.T @ rotation_in_base


def frame_in_base(frame: Any) -> tuple[str, Frame]:
    """The base body's name and the frame's transform in it."""
    base = frame.findBaseFrame().getName()
    transform = frame.findTransformInBaseFrame()
    r = rotation_xyz(vec3_array(transform.R().convertRotationToBodyFixedXYZ()))
    return base, Frame(vec3_array(transform.p()), r)


# ---- functions -------------------------------------------------------------------------


class UnsupportedPart(Exception):
    """A part the import cannot represent; the message says which and why."""


RESAMPLED_KNOTS = 81
"""knots of the spline that stands for an OpenSim function other than a line or SimmSpline"""


def read_function(fn: Any, where: str, report: ImportReport) -> Linear | Spline:
    """OpenSim function -> ``Linear`` or ``Spline`` (constants are zero-slope lines)."""
    import opensim

    kind = fn.getConcreteClassName()
    if kind == "Constant":
        return Linear(slope=0.0, intercept=opensim.Constant.safeDownCast(fn).getValue())
    if kind == "LinearFunction":
        lf = opensim.LinearFunction.safeDownCast(fn)
        return Linear(slope=lf.getSlope(), intercept=lf.getIntercept())
    if kind == "SimmSpline":
        sp = opensim.SimmSpline.safeDownCast(fn)
        n = sp.getSize()
        return Spline(x=[sp.getX(i) for i in range(n)], y=[sp.getY(i) for i in range(n)])
    if kind == "MultiplierFunction":
        mf = opensim.MultiplierFunction.safeDownCast(fn)
        return _scaled(read_function(mf.getFunction(), where, report), mf.getScale())
    # Any other function of one coordinate: sampled, as a spline, over a rotation's span.
    xs = np.linspace(-math.pi, math.pi, RESAMPLED_KNOTS)
    try:
        ys = [fn.calcValue(opensim.Vector(1, float(x))) for x in xs]
    except RuntimeError:
        raise UnsupportedPart(f"{where}: function {kind} is not supported") from None
    report.approximated.append(
        f"{where}: {kind} resampled as a spline through {len(xs)} knots over +-pi"
    )
    return Spline(x=[float(x) for x in xs], y=[float(y) for y in ys])


def _scaled(fn: Linear | Spline, scale: float) -> Linear | Spline:
    if isinstance(fn, Linear):
        return Linear(slope=fn.slope * scale, intercept=fn.intercept * scale)
    return Spline(x=fn.x, y=[y * scale for y in fn.y])


def compose(outer: Linear | Spline, inner: Linear | Spline, span: tuple[float, float]):
    """``outer(inner(x))``: exact where ``inner`` is linear, else resampled over ``span``."""
    if isinstance(inner, Linear) and inner.slope != 0:
        if isinstance(outer, Linear):
            return Linear(
                slope=outer.slope * inner.slope,
                intercept=outer.slope * inner.intercept + outer.intercept,
            )
        knots = [(x - inner.intercept) / inner.slope for x in outer.x]
        pairs = sorted(zip(knots, outer.y, strict=True))
        return Spline(x=[p[0] for p in pairs], y=[p[1] for p in pairs])
    xs = np.linspace(span[0], span[1], 41)
    return Spline(
        x=[float(x) for x in xs], y=[float(y) for y in evaluate(outer, evaluate(inner, xs))]
    )


def identity_sign(fn: Linear | Spline) -> int:
    """+1 for ``y = x``, -1 for ``y = -x``, 0 otherwise."""
    if isinstance(fn, Linear) and fn.intercept == 0 and abs(fn.slope) == 1:
        return int(fn.slope)
    return 0


@dataclass
class Coordinates:
    """What the model says about its coordinates, and its couplers: dependent ->
    (independent, function)."""

    info: dict[str, Any]
    couplers: dict[str, tuple[str, Linear | Spline]]

    def span(self, name: str) -> tuple[float, float]:
        """The coordinate's range (rad or m); an empty one (a file's min >= max) widened to
        +-1e-3 about its min, as a body's dof needs an increasing range."""
        c = self.info[name]
        low, high = c.getRangeMin(), c.getRangeMax()
        return (low, high) if high > low else (low - 1e-3, low + 1e-3)

    def set_value(self, state: Any, name: str, value: float) -> None:
        """Set coordinate ``name`` (rad or m) in ``state``, and the coordinates coupled to it
        through their couplers' functions: exactly what OpenSim's constraint projection
        finds, at a fraction of its cost (13 ms a call on Rajagopal2016). The caller
        realizes the state."""
        self.info[name].setValue(state, float(value), False)
        for dependent, (independent, function) in self.couplers.items():
            if independent == name:
                self.set_value(state, dependent, float(evaluate(function, value)))


def read_couplers(model: Any, report: ImportReport) -> dict[str, tuple[str, Linear | Spline]]:
    import opensim

    couplers: dict[str, tuple[str, Linear | Spline]] = {}
    constraints = model.getConstraintSet()
    for c in items(constraints):
        where = c.getAbsolutePathString()
        coupler = opensim.CoordinateCouplerConstraint.safeDownCast(c)
        if coupler is None or not c.get_isEnforced():
            report.dropped.append(
                f"{where}: {c.getConcreteClassName()} (of constraints, only enforced "
                "coordinate couplers are imported)"
            )
            continue
        independent = coupler.getIndependentCoordinateNames()
        if independent.getSize() != 1:
            report.dropped.append(f"{where}: a coupler of {independent.getSize()} coordinates")
            continue
        couplers[coupler.getDependentCoordinateName()] = (
            independent.get(0),
            read_function(coupler.getFunction(), where, report),
        )
    return couplers


def resolve_coupling(
    coordinate: str, fn: Linear | Spline, coords: Coordinates
) -> tuple[str, Linear | Spline]:
    """Follow couplers: ``fn`` of a dependent coordinate -> a function of a free one."""
    seen = set()
    while coordinate in coords.couplers:
        if coordinate in seen:
            raise UnsupportedPart(f"coordinate couplers form a loop through {coordinate!r}")
        seen.add(coordinate)
        independent, inner = coords.couplers[coordinate]
        fn = compose(fn, inner, coords.span(independent))
        coordinate = independent
    return coordinate, fn


@dataclass
class ImportContext:
    """What the import has learnt about the model so far."""

    model: Any
    state: Any
    coords: Coordinates
    frames: dict[str, Frame]  # segment -> its child frame in OpenSim's body frame
    report: ImportReport

    def posed(self, coordinate: str, values: Iterable[float]) -> Iterator[float]:
        """Each of ``values`` (rad or m) in turn: set on ``coordinate`` (its coupled
        coordinates with it, :meth:`Coordinates.set_value`), the state's positions realized,
        the value yielded; afterwards the coordinate is back where it was, realized."""
        before = self.coords.info[coordinate].getValue(self.state)
        try:
            for value in values:
                self.coords.set_value(self.state, coordinate, value)
                self.model.realizePosition(self.state)
                yield value
        finally:
            self.coords.set_value(self.state, coordinate, before)
            self.model.realizePosition(self.state)

    def in_segment(self, frame: Any, location: np.ndarray) -> tuple[str, np.ndarray]:
        """A point given in OpenSim ``frame``: its segment and location in the segment."""
        base, offset = frame_in_base(frame)
        return base, self.frames[base].point_in(offset.p + offset.r @ location)


def coordinate_of(socket_path: str) -> str:
    return socket_path.rstrip("/").split("/")[-1]


def read_coordinates(model: Any, report: ImportReport) -> Coordinates:
    info = {c.getName(): c for c in items(model.getCoordinateSet())}
    return Coordinates(info=info, couplers=read_couplers(model, report))
