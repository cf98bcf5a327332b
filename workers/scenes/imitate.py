"""A scene task's ``imitate`` field: track the gait clock's motion (DeepMimic-style), and
its checks against the clock.

The clock (``task.clock``, ``workers.scenes.clock``) says which motion and where in it;
imitation adds the tracking terms to the reward, starts episodes in the recorded state and
ends them early when the pose drifts. Each tracking term is an exponential kernel
``exp(-scale * error)`` in (0, 1], times its weight (see ``workers.imitation`` for each error
and its unit). Reward terms are reported as ``imitate_<name>`` beside the task's other
terms.
"""

from __future__ import annotations

from typing import Annotated

from gaitforge.workers.scenes.clock import Clock, NonNegative, Positive, StrictSpec
from pydantic import Field, model_validator


class ImitationWeights(StrictSpec):
    """Weight of each tracking term; the terms are in (0, 1], so a step earns at most the sum
    (DeepMimic: pose 0.65, velocity 0.1, end effectors 0.15, root 0.1)."""

    pose: NonNegative = 0.5
    joint_speed: NonNegative = 0.1
    feet: NonNegative = 0.15
    pelvis_height: NonNegative = 0.1
    pelvis_pitch: NonNegative = 0.05
    pelvis_speed: NonNegative = 0.1


class ImitationScales(StrictSpec):
    """Sensitivity ``k`` of each kernel ``exp(-k * error)`` (DeepMimic: pose 2, velocity 0.1,
    end effectors 40, root 10)."""

    pose: Positive = Field(default=2.0, description="1/rad^2; error: sum over joints of rad^2")
    joint_speed: Positive = Field(default=0.05, description="s^2/rad^2; sum of (rad/s)^2")
    feet: Positive = Field(default=40.0, description="1/m^2; sum over feet of m^2")
    pelvis_height: Positive = Field(default=50.0, description="1/m^2")
    pelvis_pitch: Positive = Field(default=10.0, description="1/rad^2; pitch (and list) error")
    pelvis_speed: Positive = Field(default=2.0, description="s^2/m^2; forward speed error")


class ImitationStarts(StrictSpec):
    """Reference state initialisation: where the episodes start. Those that do not start
    standing or along the lead-in start in the recorded state at the clock's phase (joint
    angles plus noise, their speeds, the pelvis's pose and speeds)."""

    standing: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.0,
        description="this fraction of the episodes starts standing instead (the reset pose; "
        "at phase 0 unless every episode starts standing), so that one policy learns both "
        "the gait and the first steps into it",
    )
    lead_in: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.0,
        description="with task.clock.lead_in, this fraction of the episodes starts part way "
        "along the way in from standing: at a uniform random time between the clock's ramp_s "
        "and the end of the lead-in's cross-fade, in the faded reference state there (phase "
        "0 at the standing start), the clock going on from there",
    )
    noise: NonNegative = Field(default=0.02, description="rad, uniform on the joint angles")

    @model_validator(mode="after")
    def _fractions_within_one(self) -> ImitationStarts:
        if self.standing + self.lead_in > 1.0:
            raise ValueError(
                "task.imitate.starts.lead_in: standing + lead_in is "
                f"{self.standing + self.lead_in:g}; at most 1 is allowed"
            )
        return self

    @property
    def all_standing(self) -> bool:
        """Every episode starts standing (no reference state starts)."""
        return self.standing >= 1.0


class Imitate(StrictSpec):
    """Track the motion of the scene's gait clock (``task.clock``)."""

    weights: ImitationWeights = ImitationWeights()
    scales: ImitationScales = ImitationScales()
    max_pose_error_rad: Positive | None = Field(
        default=0.5,
        description="rad; the episode ends when the RMS pose error over the tracked joints "
        "passes it (none: never)",
    )
    starts: ImitationStarts = ImitationStarts()


IMITATION_TERMS: tuple[str, ...] = tuple(f"imitate_{n}" for n in ImitationWeights.model_fields)
"""Reward term names of an imitation scene, beside the task's ``RewardWeights`` terms."""


def check_imitation(imitate: Imitate | None, clock: Clock | None) -> None:
    """Raise ``ValueError`` (one line naming the field) if ``imitate`` lacks what it tracks
    with: a clock, a lead-in for starts along it, or, with a lead-in, starts that play it."""
    if imitate is None:
        return
    if clock is None:
        raise ValueError(
            "task.imitate: imitation tracks the motion of the gait clock; set task.clock "
            "(e.g. {motion: walk})"
        )
    starts = imitate.starts
    if clock.lead_in is None and starts.lead_in:
        raise ValueError(
            "task.imitate.starts.lead_in: only with a task.clock.lead_in to start along"
        )
    if clock.lead_in is not None and not (starts.standing or starts.lead_in):
        raise ValueError(
            "task.clock.lead_in: the lead-in plays from a standing start; with task.imitate, "
            "set task.imitate.starts.standing or starts.lead_in above 0"
        )
