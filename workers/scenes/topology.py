"""What pruning needs to know about a body, whatever its source.

Neutral bodies give it directly. MyoSuite's MJCF bodies only exist as MuJoCo models, so their
topology is read from the compiled model (the one place ``scenes`` reaches into ``sim``, lazily).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.schema import GROUND
from gaitforge.workers.scenes.spec import MJCF_BODIES


@dataclass(frozen=True)
class Topology:
    """Names and relations of a body's parts.

    Attributes:
        dof_defaults: every non-root dof and its default value (rad or m).
        root_dofs: dofs that place the body in the world (never locked by a scene).
        root_defaults: initial values of root dofs given as hinges/slides (rad or m).
        muscle_spans: each muscle and the dofs its path crosses.
        contact_geoms: all the body's geoms that may touch the ground (feet included).
        feet: foot name -> its contact geoms (ground reaction forces are summed per foot).
    """

    dof_defaults: dict[str, float]
    root_dofs: list[str]
    root_defaults: dict[str, float]
    muscle_spans: dict[str, list[str]]
    contact_geoms: list[str]
    feet: dict[str, list[str]] = field(default_factory=dict)

    @property
    def muscles(self) -> list[str]:
        return list(self.muscle_spans)


def _neutral_topology(name: str) -> Topology:
    body = load_body(name)
    root = next(j for j in body.joints if j.parent == GROUND)
    feet: dict[str, list[str]] = {}
    for sphere in body.contact_spheres:
        if sphere.foot is not None:
            feet.setdefault(sphere.foot, []).append(sphere.name)
    return Topology(
        dof_defaults={
            d.name: d.default for j in body.ordered_joints() if j is not root for d in j.dofs
        },
        root_dofs=[d.name for d in root.dofs],
        root_defaults={d.name: d.default for d in root.dofs},
        muscle_spans={m.name: body.dofs_spanned(m) for m in body.muscles},
        contact_geoms=[c.name for c in body.contact_spheres],
        feet=feet,
    )


@lru_cache(maxsize=8)
def topology_for(body: str) -> Topology:
    """The topology of a shipped or file-given body (cached per process)."""
    if body in MJCF_BODIES:
        from gaitforge.workers.sim.mjcf_topology import mjcf_topology

        return mjcf_topology(body)
    return _neutral_topology(body)
