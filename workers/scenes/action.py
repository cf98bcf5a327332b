"""A scene's ``action`` field: what the policy's action means.

``excitations`` (the default): one entry per kept muscle, its excitation in [0, 1], held for
the control period.

``joint_targets``: one entry per kept dof, in [0, 1], read as a target angle
``base + (2 a - 1) * range_rad`` (``a = 0.5`` is the base pose). A fixed reflex layer
(``workers.reflex``) turns the targets into muscle excitations ``reflex_hz`` times a second
from the measured joint angles and speeds, through the muscles' moment arms: a muscle is
excited in proportion to the joint torque it can add toward the target, like a spinal
stretch reflex. The base pose is the imitated motion's pose at the current phase (and its
joint speeds the speed targets) in imitation scenes, else the body's default standing pose
(speed target 0). The muscles still make every force; the policy chooses where the joints
should go, which cuts the exploration from one dimension per muscle to one per dof
(Peng and van de Panne 2017 found target angles learn faster than torques for the same
motions).
"""

from __future__ import annotations

from typing import Annotated, Literal

from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field

Positive = Annotated[float, Field(gt=0)]


class ActionSpec(BaseModel):
    """The action space of a scene; see the module docstring."""

    model_config = ConfigDict(extra="forbid", **SPEC_VALUES)

    kind: Literal["excitations", "joint_targets"] = "excitations"
    kp: Annotated[float, Field(ge=0)] = Field(
        default=8.0, description="joint_targets: excitation per rad of angle error"
    )
    kd: Annotated[float, Field(ge=0)] = Field(
        default=0.5, description="joint_targets: excitation per rad/s of speed error"
    )
    range_rad: Positive = Field(
        default=0.6, description="joint_targets: the target's span either side of the base pose"
    )
    reflex_hz: Annotated[float, Field(gt=0, le=2000)] = Field(
        default=500.0,
        description="joint_targets: how often the reflex layer recomputes the excitations",
    )

    @property
    def targets(self) -> bool:
        return self.kind == "joint_targets"
