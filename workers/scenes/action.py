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

``reflex_gait``: a spinal reflex gait controller (``workers.gait_reflex``, after Song and
Geyer 2015) makes the excitations each control step from the body's sensed muscle forces
and lengths, foot loads, joint angles and trunk lean, with the named ``parameters`` (the
rest at their defaults) and the body's ``wiring``. The policy's action [n_muscles] in
[0, 1] adds ``(2 a - 1) * residual`` to each muscle's excitation (``a = 0.5`` adds nothing),
so that PPO can learn on top of a tuned controller. Episodes start from the controller's
start pose (``pose.*`` parameters), at rest, or moving forward at ``start_speed`` (a
mid-stride start, as the 2019 challenge's baseline).
"""

from __future__ import annotations

from typing import Annotated, Literal

from gaitforge.workers.scenes.reflex_parameters import parameter_vector
from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field, model_validator

Positive = Annotated[float, Field(gt=0)]


class ActionSpec(BaseModel):
    """The action space of a scene; see the module docstring."""

    model_config = ConfigDict(extra="forbid", **SPEC_VALUES)

    kind: Literal["excitations", "joint_targets", "reflex_gait"] = "excitations"
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

    wiring: str | None = Field(
        default=None,
        description="reflex_gait: a wiring file (default: the one shipped for the body)",
    )
    parameters: dict[str, float] = Field(
        default_factory=dict,
        description="reflex_gait: controller parameters by name (the rest at their defaults)",
    )
    residual: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.2, description="reflex_gait: the policy's excitation span either side of 0"
    )
    start_speed: Annotated[float, Field(ge=0, le=3)] = Field(
        default=0.0,
        description="reflex_gait: m/s forward at the start (0: from rest; else mid-stride)",
    )

    @model_validator(mode="after")
    def _check_gait(self) -> ActionSpec:
        if self.kind != "reflex_gait" and (
            self.wiring is not None or self.parameters or self.start_speed
        ):
            raise ValueError(
                "action.wiring, action.parameters and action.start_speed are for kind reflex_gait"
            )
        parameter_vector(self.parameters)  # names and bounds
        return self

    @property
    def targets(self) -> bool:
        return self.kind == "joint_targets"

    @property
    def gait(self) -> bool:
        return self.kind == "reflex_gait"
