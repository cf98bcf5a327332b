"""Which of a body's muscles and dofs the reflex gait controller drives and reads: body data.

A wiring file names, for each leg, the foot (a simulator foot name), the four dofs the
controller reads (hip flexion, hip adduction, knee, ankle; each with the sign that makes
flexion, adduction and dorsiflexion positive) and, for each of the eleven muscle groups of
Song and Geyer (2015), the body's muscles in it with a weight. A group's sensed length and
force are the weighted means of its muscles'; a muscle's excitation is the weighted sum of
its groups' (clipped to [0, 1]). A planar body has no ``HAB`` or ``HAD`` and no
``hip_adduction``: its frontal-plane circuits are left out.

Shipped wirings live in ``workers/bodies/data/reflex/<body>.yaml``; a scene names another file
with ``action.wiring`` (a user's imported body).
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from gaitforge.workers.spec_io import SpecError, load_yaml_model
from pydantic import BaseModel, ConfigDict, Field

GROUPS = ("HAB", "HAD", "HFL", "GLU", "HAM", "RF", "VAS", "BFSH", "GAS", "SOL", "TA")
"""Song and Geyer's (2015) muscle groups: hip abductors, adductors, flexors, glutei,
hamstrings, rectus femoris, vasti, biceps femoris short head, gastrocnemius, soleus, tibialis
anterior."""
SAGITTAL_GROUPS = GROUPS[2:]
"""The groups a planar body needs (no hip abductors or adductors)."""

Group = Literal["HAB", "HAD", "HFL", "GLU", "HAM", "RF", "VAS", "BFSH", "GAS", "SOL", "TA"]
Sign = Literal[-1, 1]
Weight = Annotated[float, Field(gt=0, le=1)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class WiredDof(_Strict):
    """A dof the controller reads, and the sign that turns it into the controller's
    convention (flexion, adduction, dorsiflexion positive)."""

    name: str
    sign: Sign = 1


class Leg(_Strict):
    """One leg's wiring."""

    foot: str = Field(description="the simulator's foot name (its ground reaction force)")
    hip_flexion: WiredDof
    hip_adduction: WiredDof | None = Field(default=None, description="None on a planar body")
    knee: WiredDof = Field(description="signed so that knee flexion is positive")
    ankle: WiredDof = Field(description="signed so that dorsiflexion is positive")
    groups: dict[Group, dict[str, Weight]] = Field(
        description="group -> {muscle: weight}; the sagittal groups are required"
    )

    def model_post_init(self, _context: object) -> None:
        missing = [g for g in SAGITTAL_GROUPS if not self.groups.get(g)]
        if missing:
            raise ValueError(f"groups {missing} need at least one muscle each")
        frontal = [g for g in ("HAB", "HAD") if self.groups.get(g)]
        if self.hip_adduction is None and frontal:
            raise ValueError(f"groups {frontal} need hip_adduction")
        if self.hip_adduction is not None and len(frontal) != 2:
            raise ValueError("a leg with hip_adduction needs both HAB and HAD")

    @property
    def frontal(self) -> bool:
        return self.hip_adduction is not None

    @property
    def dofs(self) -> dict[str, WiredDof | None]:
        """The four dofs the controller reads, by field, in its order (hip flexion,
        adduction, knee, ankle); adduction is None on a planar body."""
        return {
            "hip_flexion": self.hip_flexion,
            "hip_adduction": self.hip_adduction,
            "knee": self.knee,
            "ankle": self.ankle,
        }


class Wiring(_Strict):
    """A body's wiring for ``workers.gait_reflex``: the right and the left leg."""

    body: str
    right: Leg
    left: Leg

    def legs(self) -> tuple[Leg, Leg]:
        return self.right, self.left


def _data_dir() -> Path:
    return Path(str(resources.files("gaitforge.workers.bodies") / "data" / "reflex"))


def shipped_wirings() -> list[str]:
    """The bodies with a shipped wiring."""
    return sorted(p.stem for p in _data_dir().glob("*.yaml"))


@lru_cache(maxsize=16)
def load_wiring(body: str, path: str | None = None) -> Wiring:
    """The wiring of ``body`` at ``path``, else the one shipped for it.

    Raises:
        SpecError: no shipped wiring for ``body``, the file is invalid, or it wires another
            body.
    """
    if path is None:
        shipped = _data_dir() / f"{body}.yaml"
        if not shipped.exists():
            raise SpecError(
                f"action.wiring: body {body!r} has no shipped reflex wiring (shipped: "
                f"{shipped_wirings()}); name a wiring file (see workers/bodies/reflex_wiring.py)"
            )
        path = str(shipped)
    wiring = load_yaml_model(Path(path), Wiring)
    if wiring.body != body:
        raise SpecError(
            f"action.wiring {path!r} wires body {wiring.body!r}, not the scene's {body!r}"
        )
    return wiring


def check_wiring_names(wiring: Wiring, dofs: set[str], muscles: set[str]) -> None:
    """Raise ``SpecError`` naming the leg and field where ``wiring`` names a dof or muscle
    its body (with ``dofs`` and ``muscles``) lacks: checked when a scene loads, before any
    simulator is built. (Whether the scene keeps them is checked when the controller is
    built on the pruned simulator.)"""
    for side, leg in zip(("right", "left"), wiring.legs(), strict=True):
        for key, dof in leg.dofs.items():
            if dof is not None and dof.name not in dofs:
                raise SpecError(
                    f"action.wiring: {side}.{key}: body {wiring.body!r} has no dof "
                    f"{dof.name!r}; it has {sorted(dofs)}"
                )
        for group, members in leg.groups.items():
            for muscle in members:
                if muscle not in muscles:
                    raise SpecError(
                        f"action.wiring: {side}.groups.{group}: body {wiring.body!r} has no "
                        f"muscle {muscle!r}; it has {sorted(muscles)}"
                    )
