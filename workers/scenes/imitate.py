"""A scene task's ``imitate`` field: track a recorded gait (DeepMimic-style), and its checks
against the body (the motion exists, the scene keeps some of its joints).

Each tracking term is an exponential kernel ``exp(-scale * error)`` in (0, 1], times its
weight (see ``workers.imitation`` for each error and its unit). Reward terms are reported as
``imitate_<name>`` beside the task's other terms.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Literal

from gaitforge.workers.bodies.topology import Topology
from gaitforge.workers.motions import MotionError, available_motions, load_motion
from gaitforge.workers.spec_types import MAX_REF_LENGTH, SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field, model_validator

NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]


class _Strict(BaseModel):
    """Unknown fields are errors, values frozen, numbers strict and finite."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)


class ImitationWeights(_Strict):
    """Weight of each tracking term; the terms are in (0, 1], so a step earns at most the sum
    (DeepMimic: pose 0.65, velocity 0.1, end effectors 0.15, root 0.1)."""

    pose: NonNegative = 0.5
    joint_speed: NonNegative = 0.1
    feet: NonNegative = 0.15
    pelvis_height: NonNegative = 0.1
    pelvis_pitch: NonNegative = 0.05
    pelvis_speed: NonNegative = 0.1


class ImitationScales(_Strict):
    """Sensitivity ``k`` of each kernel ``exp(-k * error)`` (DeepMimic: pose 2, velocity 0.1,
    end effectors 40, root 10)."""

    pose: Positive = Field(default=2.0, description="1/rad^2; error: sum over joints of rad^2")
    joint_speed: Positive = Field(default=0.05, description="s^2/rad^2; sum of (rad/s)^2")
    feet: Positive = Field(default=40.0, description="1/m^2; sum over feet of m^2")
    pelvis_height: Positive = Field(default=50.0, description="1/m^2")
    pelvis_pitch: Positive = Field(default=10.0, description="1/rad^2; pitch (and list) error")
    pelvis_speed: Positive = Field(default=2.0, description="s^2/m^2; forward speed error")


class ImitationInit(_Strict):
    """Reference state initialisation: where each episode starts in the motion; or, with
    ``start: standing``, from the body's standing reset with the gait phase at 0 (or random)
    (with all weights 0 the motion is then only a phase clock and, with joint-target actions,
    the targets' base pose: a scene that learns a task from standing with no imitation
    reward)."""

    start: Literal["motion", "standing"] = Field(
        default="motion", description="motion: in the reference state; standing: the reset pose"
    )
    random_phase: bool = Field(default=True, description="a uniform random phase; else 0")
    mirror: bool = Field(default=True, description="left and right swapped at random (p=0.5)")
    noise: NonNegative = Field(default=0.02, description="rad, uniform on the joint angles")
    standing_fraction: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.0,
        description="with start: motion, this fraction of the episodes starts standing "
        "instead, at phase 0 (the way a scene with start: standing and random_phase: false "
        "starts), so that one policy learns both the walk and the first steps into it",
    )
    ramp_s: NonNegative = Field(
        default=0.0,
        description="s; after a standing start, joint-target actions' base pose (and its "
        "speeds) and the pose that the pose term and max_pose_error_rad compare with blend "
        "linearly from the standing pose into the motion's over this time (0: the motion's "
        "pose at once)",
    )
    lead_in_fraction: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.0,
        description="with start: motion and a lead_in, this fraction of the episodes starts "
        "part way along the way in from standing: at a uniform random time between ramp_s "
        "and the end of the lead-in's cross-fade, in the faded reference state there (phase "
        "0 at the standing start), the clock going on from there (reference state "
        "initialisation along the lead-in, so that its fade is learned from every point)",
    )

    @model_validator(mode="after")
    def _fractions_with_motion_start(self) -> ImitationInit:
        for name in ("standing_fraction", "lead_in_fraction"):
            if self.start == "standing" and getattr(self, name):
                raise ValueError(
                    f"task.imitate.init.{name}: only with start: motion (with start: "
                    "standing every episode starts standing)"
                )
        if self.standing_fraction + self.lead_in_fraction > 1.0:
            raise ValueError(
                "task.imitate.init.lead_in_fraction: standing_fraction + lead_in_fraction is "
                f"{self.standing_fraction + self.lead_in_fraction:g}; at most 1 is allowed"
            )
        return self


class LeadIn(_Strict):
    """After a standing start, play another motion first and cross-fade from it into the
    scene's (``workers.motions.playback``): a run that starts as a walk. The phase clock,
    the joint targets' base, the pose the tracking terms compare with and (with
    ``speed_target_from_clock``) the target speed all follow the fade."""

    motion: str = Field(
        max_length=MAX_REF_LENGTH,
        description="a motion shipped for the body (or a file): e.g. walk",
    )
    tempo: Annotated[float, Field(ge=0.5, le=2.0)] = Field(
        default=1.0, description="the lead-in motion plays this many times faster"
    )
    hold_s: NonNegative = Field(
        description="s from the episode's start in the lead-in motion alone (the standing "
        "ramp, init.ramp_s, included)"
    )
    crossfade_s: Positive = Field(description="s of the linear blend into the scene's motion")


class Imitate(_Strict):
    """Track motion ``motion`` of the scene's body (``workers.motions``)."""

    motion: str = Field(
        max_length=MAX_REF_LENGTH,
        description="a motion shipped for the body, or a motion file path",
    )
    weights: ImitationWeights = ImitationWeights()
    scales: ImitationScales = ImitationScales()
    max_pose_error_rad: Positive | None = Field(
        default=0.5,
        description="rad; the episode ends when the RMS pose error over the tracked joints "
        "passes it (none: never)",
    )
    init: ImitationInit = ImitationInit()
    tempo: Annotated[float, Field(ge=0.5, le=2.0)] = Field(
        default=1.0,
        description="the motion plays this many times faster (a shorter period; joint, pelvis "
        "and forward speeds times tempo): a walk at another pace with the same strides; in a "
        "scene that draws its target speed (task.target_speed_range), times (draw / "
        "task.target_speed): the same strides at the drawn speed (the lead-in keeps its tempo)",
    )
    lead_in: LeadIn | None = Field(
        default=None,
        description="after a standing start (init.start: standing or standing_fraction), "
        "start in this motion and cross-fade into ``motion``",
    )
    speed_target_from_clock: bool = Field(
        default=False,
        description="the target_speed reward term asks for the smaller of task.target_speed "
        "and the reference's forward speed now (ramped from standing, faded from the lead-in), "
        "so a standing start is not asked for full speed at once; the observation keeps "
        "task.target_speed",
    )

    @model_validator(mode="after")
    def _lead_in_needs_standing_starts(self) -> Imitate:
        init = self.init
        starts_in_lead_in = init.standing_fraction or init.lead_in_fraction
        if self.lead_in is not None and init.start != "standing" and not starts_in_lead_in:
            raise ValueError(
                "task.imitate.lead_in: only with standing starts (init.start: standing, or "
                "init.standing_fraction or init.lead_in_fraction > 0): the lead-in plays from "
                "a standing start"
            )
        if self.lead_in is None and init.lead_in_fraction:
            raise ValueError(
                "task.imitate.init.lead_in_fraction: only with a task.imitate.lead_in to "
                "start along"
            )
        return self


IMITATION_TERMS: tuple[str, ...] = tuple(f"imitate_{n}" for n in ImitationWeights.model_fields)
"""Reward term names of an imitation scene, beside the task's ``RewardWeights`` terms."""


def tracked_joints(
    imitate: Imitate, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> list[str]:
    """The motion's joints that the scene keeps, in the motion's order.

    Raises:
        ValueError: one line naming the field: the motion is unknown or invalid (the
            available ones listed), the body lacks one of its joints, or the scene keeps
            none of them.
    """
    return _kept_joints_of(imitate.motion, "task.imitate.motion", body, kept, topology)


def _kept_joints_of(
    name: str, field: str, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> list[str]:
    """Motion ``name``'s joints that the scene keeps; errors name ``field``."""
    try:
        motion = load_motion(body, name)
    except MotionError as exc:
        raise ValueError(f"{field}: {exc}") from None
    missing = [j for j in motion.joints if j not in topology.dof_defaults]
    if missing:
        raise ValueError(
            f"{field}: motion {name!r} tracks joints {missing} that body "
            f"{body!r} lacks; available motions: {available_motions(body)}"
        )
    kept_set = set(topology.dof_defaults if kept == "all" else kept)
    tracked = [j for j in motion.joints if j in kept_set]
    if not tracked:
        raise ValueError(
            f"{field}: the scene keeps none of the joints of motion {name!r} "
            f"{motion.joints}; keep.joints must include some"
        )
    return tracked


def check_imitation(
    imitate: Imitate | None, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> None:
    """Raise ``ValueError`` (one line naming the field) if ``imitate`` does not fit the body:
    no pelvis root to place, or see :func:`tracked_joints`."""
    if imitate is None:
        return
    if not topology.root_dofs:
        raise ValueError(
            f"task.imitate: body {body!r} has no free pelvis (root) to place; imitation needs "
            "a legged body (gait2d, myoleg)"
        )
    tracked = tracked_joints(imitate, body, kept, topology)
    if imitate.lead_in is not None:
        field = "task.imitate.lead_in.motion"
        lead_tracked = _kept_joints_of(imitate.lead_in.motion, field, body, kept, topology)
        if lead_tracked != tracked:
            raise ValueError(
                f"task.imitate.lead_in.motion: motion {imitate.lead_in.motion!r} tracks "
                f"{lead_tracked}, motion {imitate.motion!r} tracks {tracked}: a cross-fade needs "
                "the same joints"
            )
