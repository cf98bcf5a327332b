"""A scene task's ``clock`` field: the gait clock, the phase of a recorded gait played with
the episode's time, and its checks against the body.

The clock is a task feature of its own. The policy observes its phase (``phase_sin``,
``phase_cos``, ``phase_mirror``); joint-target actions are offsets around the motion's pose at
that phase; with ``speed_target_from_clock`` the target-speed term asks for the clock's
speed until it reaches the task's. Tracking the motion (reward terms, starts in the recorded
state, an early end when the pose drifts) is imitation, ``task.imitate``
(``workers.scenes.imitate``), which needs a clock to say where in the motion it is.

A scene with a clock and no imitation starts every episode standing (the body's reset pose);
the targets' base ramps from the standing pose into the motion over ``ramp_s``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Literal

from gaitforge.workers.bodies.topology import Topology
from gaitforge.workers.motions import MotionError, available_motions, load_motion
from gaitforge.workers.spec_types import MAX_REF_LENGTH, SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field

NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]
Tempo = Annotated[float, Field(ge=0.5, le=2.0)]


class StrictSpec(BaseModel):
    """Unknown fields are errors, values frozen, numbers strict and finite."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)


class LeadIn(StrictSpec):
    """After a standing start, play another motion first and cross-fade from it into the
    clock's (``workers.motions.playback``): a run that starts as a walk. The phase, the joint
    targets' base, the pose imitation compares with and (with ``speed_target_from_clock``)
    the target speed all follow the fade."""

    motion: str = Field(
        max_length=MAX_REF_LENGTH,
        description="a motion shipped for the body (or a file): e.g. walk",
    )
    tempo: Tempo = Field(default=1.0, description="the lead-in motion plays this many times faster")
    hold_s: NonNegative = Field(
        description="s from the episode's start in the lead-in motion alone (the standing "
        "ramp, ramp_s, included)"
    )
    crossfade_s: Positive = Field(description="s of the linear blend into the clock's motion")


class Clock(StrictSpec):
    """The phase of motion ``motion`` of the scene's body (``workers.motions``), played with
    the episode's time."""

    motion: str = Field(
        max_length=MAX_REF_LENGTH,
        description="a motion shipped for the body, or a motion file path",
    )
    tempo: Tempo = Field(
        default=1.0,
        description="the motion plays this many times faster (a shorter period; joint, pelvis "
        "and forward speeds times tempo): a walk at another pace with the same strides; in a "
        "scene that draws its target speed (task.target_speed_range), times (draw / "
        "task.target_speed): the same strides at the drawn speed (the lead-in keeps its tempo)",
    )
    lead_in: LeadIn | None = Field(
        default=None,
        description="after a standing start, start in this motion and cross-fade into ``motion``",
    )
    speed_target_from_clock: bool = Field(
        default=False,
        description="the target_speed reward term asks for the smaller of task.target_speed "
        "and the clock's forward speed now (ramped from standing, faded from the lead-in), "
        "so a standing start is not asked for full speed at once; the observation keeps "
        "task.target_speed",
    )
    random_phase: bool = Field(
        default=True,
        description="each episode starts at a uniform random phase, else at 0 (a standing "
        "start in a scene that also starts in the recorded state is always at 0)",
    )
    mirror: bool = Field(
        default=True,
        description="left and right swapped at random (p=0.5) each episode: the other leg leads",
    )
    ramp_s: NonNegative = Field(
        default=0.0,
        description="s; after a standing start, joint-target actions' base pose (and its "
        "speeds), the clock's speed and the pose imitation compares with blend linearly from "
        "the standing pose into the motion's over this time (0: the motion's pose at once)",
    )


def kept_motion_joints(
    name: str, field: str, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> list[str]:
    """Motion ``name``'s joints that the scene keeps, in the motion's order.

    Raises:
        ValueError: one line naming ``field``: the motion is unknown or invalid (the available
            ones listed), the body lacks one of its joints, or the scene keeps none of them.
    """
    try:
        motion = load_motion(body, name)
    except MotionError as exc:
        raise ValueError(f"{field}: {exc}") from None
    missing = [j for j in motion.joints if j not in topology.dof_defaults]
    if missing:
        raise ValueError(
            f"{field}: motion {name!r} has joints {missing} that body "
            f"{body!r} lacks; available motions: {available_motions(body)}"
        )
    kept_set = set(topology.dof_defaults if kept == "all" else kept)
    joints = [j for j in motion.joints if j in kept_set]
    if not joints:
        raise ValueError(
            f"{field}: the scene keeps none of the joints of motion {name!r} "
            f"{motion.joints}; keep.joints must include some"
        )
    return joints


def clock_joints(
    clock: Clock, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> list[str]:
    """The clock motion's joints that the scene keeps (those imitation tracks), in the
    motion's order; see :func:`kept_motion_joints` for the errors."""
    return kept_motion_joints(clock.motion, "task.clock.motion", body, kept, topology)


def check_clock(
    clock: Clock | None, body: str, kept: Sequence[str] | Literal["all"], topology: Topology
) -> None:
    """Raise ``ValueError`` (one line naming the field) if ``clock`` does not fit the body: no
    pelvis root (a clock plays a gait), or see :func:`kept_motion_joints`; a lead-in must
    have the same joints as the motion it fades into."""
    if clock is None:
        return
    if not topology.root_dofs:
        raise ValueError(
            f"task.clock: body {body!r} has no free pelvis (root); a gait clock needs a legged "
            "body (gait2d, myoleg)"
        )
    joints = clock_joints(clock, body, kept, topology)
    if clock.lead_in is not None:
        field = "task.clock.lead_in.motion"
        lead_joints = kept_motion_joints(clock.lead_in.motion, field, body, kept, topology)
        if lead_joints != joints:
            raise ValueError(
                f"{field}: motion {clock.lead_in.motion!r} has {lead_joints}, motion "
                f"{clock.motion!r} has {joints}: a cross-fade needs the same joints"
            )
