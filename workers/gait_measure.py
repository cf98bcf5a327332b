"""The named measure a reflex controller is tuned on, and one candidate's score under it.

``gait`` (after SCONE's gait measure): over each episode from rest, with its reset noise,

    cost = fall * (1 - alive) + speed * shortfall + effort * excitation_sq

where ``alive`` is the fraction of the episode's time before the body fell (a simulator
failure counts as a fall), ``shortfall`` (m/s) is how far the episode's mean forward speed
(distance over the episode's full length, so that a fall stops the clock) lies outside
``[min_speed, max_speed]``, and ``excitation_sq`` the mean over steps and muscles of the
squared excitation. A candidate's cost is the mean over its episodes; its parts are reported
beside it. Lower is better.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Annotated, Literal, Protocol

import numpy as np
from gaitforge.workers.sim.base import HEALTHY
from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    import threading

    from gaitforge.workers.env import MuscleEnv

NonNegative = Annotated[float, Field(ge=0)]


class GaitMeasure(BaseModel):
    """The measure's settings (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)

    name: Literal["gait"] = "gait"
    min_speed: NonNegative = Field(default=1.0, description="m/s")
    max_speed: NonNegative = Field(default=1.6, description="m/s")
    fall: NonNegative = Field(default=1.0, description="cost of falling at the start")
    speed: NonNegative = Field(default=1.0, description="cost per m/s outside the speed band")
    effort: NonNegative = Field(default=0.1, description="cost per mean squared excitation")

    @model_validator(mode="after")
    def _check_band(self) -> GaitMeasure:
        if self.max_speed < self.min_speed:
            raise ValueError(f"max_speed {self.max_speed} is below min_speed {self.min_speed}")
        return self


@dataclass(frozen=True)
class CandidateScore:
    """One candidate's score: its cost and the parts it is made of (means over episodes).

    Attributes:
        cost: the measure's cost (lower is better).
        alive: fraction of the episodes' time before a fall, 0..1.
        falls: fraction of episodes that fell, 0..1.
        speed: m/s, mean forward speed (distance over the full episode length).
        excitation_sq: mean squared excitation.
        episodes: episodes run.
        env_steps: control steps simulated.
    """

    cost: float
    alive: float
    falls: float
    speed: float
    excitation_sq: float
    episodes: int
    env_steps: int

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def score_candidate(
    env: MuscleEnv, parameters: np.ndarray, seeds: list[int], measure: GaitMeasure
) -> CandidateScore:
    """Run ``env``'s reflex gait controller with ``parameters`` [n_parameters] for one
    episode per seed (no residual: the action is 0.5) and score them.

    Raises:
        ValueError: the env's scene has no reflex gait controller.
    """
    if env.gait is None:
        raise ValueError(f"scene {env.scene.name!r}: action.kind is not reflex_gait")
    env.gait.parameters = np.asarray(parameters, dtype=np.float64)
    neutral = np.full(env.action_space.shape, 0.5, dtype=np.float32)
    length = env.scene.steps_per_episode
    rows, steps_total = [], 0
    for seed in seeds:
        env.reset(seed=seed)
        effort, steps, fell, distance = 0.0, 0, False, 0.0
        for steps in range(1, length + 1):  # noqa: B007 (read after the loop)
            _, _, terminated, truncated, info = env.step(neutral)
            effort += float(np.mean(env.excitation**2))
            distance = info["distance"]
            if terminated:
                fell = info.get("fell", False) or info["health"] != HEALTHY
                break
            if truncated:
                break
        steps_total += steps
        alive = steps / length if fell else 1.0
        speed = distance / env.scene.episode_s
        shortfall = max(measure.min_speed - speed, speed - measure.max_speed, 0.0)
        excitation_sq = effort / steps
        cost = (
            measure.fall * (1.0 - alive)
            + measure.speed * shortfall
            + measure.effort * excitation_sq
        )
        rows.append((cost, alive, float(fell), speed, excitation_sq))
    cost, alive, falls, speed, excitation_sq = np.mean(rows, axis=0)
    return CandidateScore(
        cost=float(cost),
        alive=float(alive),
        falls=float(falls),
        speed=float(speed),
        excitation_sq=float(excitation_sq),
        episodes=len(seeds),
        env_steps=steps_total,
    )


class CandidateScorer(Protocol):
    """What scores a generation of candidates: a ``WorkerPool`` (on its actors) or a
    ``RolloutWorker`` (in this process)."""

    def score_candidates(
        self,
        candidates: list[np.ndarray],
        seeds: list[int],
        measure: GaitMeasure,
        stop: threading.Event | None = None,
    ) -> list[CandidateScore]:
        """Each candidate's score [n_parameters] -> :class:`CandidateScore`, in order;
        raises ``StopRequested`` once ``stop`` is set."""
        ...
