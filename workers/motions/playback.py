"""How a motion is played: faster or slower (tempo), and after a lead-in motion it cross-fades
from (a walk before a run).

A cross-fade plays ``lead`` alone for ``hold_s`` seconds, then blends linearly into ``main``
over ``crossfade_s`` seconds, then plays ``main`` alone. Both motions share one gait phase
(both start their cycle at the right foot's contact), which advances at the lead-in's rate
(``tempo / period_s``, cycles/s), then at a rate blended by the same weight, then at the main
motion's, so the phase is continuous and its rate too:

    rate(t) = (1 - w(t)) * r_lead + w(t) * r_main,   w(t) = clip((t - hold_s) / crossfade_s, 0, 1)
    phase(t) = integral of rate from 0 to t   (closed form: :meth:`CrossFade.cycles`)

The state at ``t`` is both motions' states at that phase blended by ``w(t)`` (angles, speeds,
pelvis, feet; stance from the motion that weighs more). The blended speeds are the blend of
the speeds, leaving out ``dw/dt`` times the difference of the poses (the fade's own motion).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from gaitforge.workers.motions.model import Motion, MotionState


def faster(state: MotionState, tempo: float) -> MotionState:
    """``state`` of the motion played ``tempo`` times faster: every speed times ``tempo``."""
    if tempo == 1.0:
        return state
    return replace(
        state,
        joint_speeds={j: v * tempo for j, v in state.joint_speeds.items()},
        pelvis_angular_speed=tuple(w * tempo for w in state.pelvis_angular_speed),  # type: ignore[arg-type]
        pelvis_vertical_speed=state.pelvis_vertical_speed * tempo,
        forward_speed=state.forward_speed * tempo,
    )


def blend(a: MotionState, b: MotionState, weight: float) -> MotionState:
    """``(1 - weight) * a + weight * b`` field by field (``weight`` in [0, 1]); joints, feet
    and phase from ``a``'s keys; stance from the state that weighs more. Weights 0 and 1
    give ``a`` and ``b`` exactly."""
    if weight <= 0.0:
        return a
    if weight >= 1.0:
        return b

    def mix(x: float, y: float) -> float:
        return x + weight * (y - x)

    return MotionState(
        phase=a.phase,
        joints={j: mix(v, b.joints[j]) for j, v in a.joints.items()},
        joint_speeds={j: mix(v, b.joint_speeds[j]) for j, v in a.joint_speeds.items()},
        pelvis_height=mix(a.pelvis_height, b.pelvis_height),
        pelvis_pitch=mix(a.pelvis_pitch, b.pelvis_pitch),
        pelvis_list=mix(a.pelvis_list, b.pelvis_list),
        pelvis_rotation=mix(a.pelvis_rotation, b.pelvis_rotation),
        pelvis_angular_speed=tuple(  # type: ignore[arg-type]
            mix(x, y) for x, y in zip(a.pelvis_angular_speed, b.pelvis_angular_speed, strict=True)
        ),
        pelvis_vertical_speed=mix(a.pelvis_vertical_speed, b.pelvis_vertical_speed),
        forward_speed=mix(a.forward_speed, b.forward_speed),
        feet_rel_pelvis={
            f: tuple(mix(x, y) for x, y in zip(v, b.feet_rel_pelvis[f], strict=True))  # type: ignore[misc]
            for f, v in a.feet_rel_pelvis.items()
        },
        stance=dict(a.stance if weight < 0.5 else b.stance),
    )


@dataclass(frozen=True)
class CrossFade:
    """``lead`` (at ``lead_tempo``) for ``hold_s`` s, then into ``main`` (at ``main_tempo``)
    over ``crossfade_s`` s. Times are s from the episode's start."""

    lead: Motion
    lead_tempo: float
    main: Motion
    main_tempo: float
    hold_s: float
    crossfade_s: float

    @property
    def lead_rate(self) -> float:
        """Cycles/s of the lead-in motion."""
        return self.lead_tempo / self.lead.period_s

    @property
    def main_rate(self) -> float:
        """Cycles/s of the main motion."""
        return self.main_tempo / self.main.period_s

    def weight(self, t: float) -> float:
        """How far (0..1) the fade has gone into the main motion at ``t`` s."""
        return min(1.0, max(0.0, (t - self.hold_s) / self.crossfade_s))

    def cycles(self, t: float) -> float:
        """Gait cycles played by ``t`` s (the phase before wrapping): the integral of the
        blended rate."""
        a, b, hold, fade = self.lead_rate, self.main_rate, self.hold_s, self.crossfade_s
        if t <= hold:
            return a * t
        into = min(t - hold, fade)
        played = a * hold + a * into + (b - a) * into**2 / (2.0 * fade)
        return played + b * max(0.0, t - hold - fade)

    def at(self, t: float, phase0: float = 0.0) -> MotionState:
        """The blended state at ``t`` s (phase ``phase0 + cycles(t)``, speeds at each
        motion's tempo)."""
        phase = (phase0 + self.cycles(t)) % 1.0
        lead = faster(self.lead.at(phase), self.lead_tempo)
        main = faster(self.main.at(phase), self.main_tempo)
        return blend(lead, main, self.weight(t))
