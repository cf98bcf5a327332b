"""What pruning needs to know about a body, whatever its source: its topology.

Neutral bodies give it from their description. MyoSuite's MJCF bodies (``MJCF_BODIES``) exist
only as MuJoCo models: their topology is committed data, ``data/topology/<body>.yaml``,
written from the compiled model by ``python bench/data/mjcf_topology.py --write``
(a test checks it against the installed myo-sim), so reading it needs no simulator.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.schema import GROUND
from gaitforge.workers.spec_io import SpecError

MJCF_BODIES: tuple[str, ...] = ("myoleg", "myoelbow")
"""Bodies loaded from MyoSuite's MJCF files (MuJoCo only); all others are neutral bodies."""


@dataclass(frozen=True)
class Topology:
    """Names and relations of a body's parts (every mapping in the body's order).

    Attributes:
        dof_defaults: every free non-root dof and its default value (rad or m).
        root_dofs: free dofs that place the body in the world (never locked by a scene).
        root_defaults: initial values of root dofs given as hinges/slides (rad or m).
        muscle_spans: each muscle and the dofs its path crosses.
        contact_geoms: all the body's geoms that may touch the ground (feet included).
        feet: foot name -> its contact geoms (ground reaction forces are summed per foot).
        coupled: dofs that are functions of another (imported bodies' coupled dofs) -> the
            free dof that drives each; they are never kept or locked on their own: they
            follow their driver.
    """

    dof_defaults: dict[str, float]
    root_dofs: list[str]
    root_defaults: dict[str, float]
    muscle_spans: dict[str, list[str]]
    contact_geoms: list[str]
    feet: dict[str, list[str]] = field(default_factory=dict)
    coupled: dict[str, str] = field(default_factory=dict)

    @property
    def muscles(self) -> list[str]:
        return list(self.muscle_spans)

    def to_data(self) -> dict[str, Any]:
        """Plain data (YAML-ready; order kept; no ``coupled`` when there is none)."""
        data = asdict(self)
        if not self.coupled:
            del data["coupled"]
        return data

    @classmethod
    def from_data(cls, data: dict[str, Any]) -> Topology:
        return cls(
            dof_defaults={str(k): float(v) for k, v in data["dof_defaults"].items()},
            root_dofs=[str(d) for d in data["root_dofs"]],
            root_defaults={str(k): float(v) for k, v in data["root_defaults"].items()},
            muscle_spans={str(k): [str(d) for d in v] for k, v in data["muscle_spans"].items()},
            contact_geoms=[str(g) for g in data["contact_geoms"]],
            feet={str(k): [str(g) for g in v] for k, v in data.get("feet", {}).items()},
            coupled={str(k): str(v) for k, v in data.get("coupled", {}).items()},
        )


def topology_file(body: str) -> Path:
    """The committed topology of an MJCF body (``MJCF_BODIES``)."""
    return Path(str(resources.files("gaitforge.workers.bodies") / "data" / "topology")) / (
        f"{body}.yaml"
    )


def _mjcf_topology(body: str) -> Topology:
    path = topology_file(body)
    try:
        return Topology.from_data(yaml.safe_load(path.read_text()))
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
        raise SpecError(
            f"{path}: body {body!r}: no readable topology ({exc}); write it with "
            "python bench/data/mjcf_topology.py --write"
        ) from None


def _neutral_topology(name: str) -> Topology:
    body = load_body(name)
    root = next(j for j in body.joints if j.parent == GROUND)
    feet: dict[str, list[str]] = {}
    for sphere in body.contact_spheres:
        if sphere.foot is not None:
            feet.setdefault(sphere.foot, []).append(sphere.name)
    free = [d for d in root.dofs if d.coupled is None]
    return Topology(
        dof_defaults={
            d.name: d.default
            for j in body.ordered_joints()
            if j is not root
            for d in j.dofs
            if d.coupled is None
        },
        root_dofs=[d.name for d in free],
        root_defaults={d.name: d.default for d in free},
        muscle_spans={m.name: body.dofs_spanned(m) for m in body.muscles},
        contact_geoms=[c.name for c in body.contact_spheres],
        feet=feet,
        coupled=body.coupled_dofs,
    )


@lru_cache(maxsize=8)
def topology_for(body: str) -> Topology:
    """The topology of a shipped or file-given body (cached per process)."""
    if body in MJCF_BODIES:
        return _mjcf_topology(body)
    return _neutral_topology(body)
