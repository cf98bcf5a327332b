"""The episode metrics, in one table: each metric's one name, its unit, what it means, how it
is aggregated over episodes and how it is read from a training episode and from an
evaluation. Promotion rules (``learner.stage_spec``), the curriculum's windows
(``learner.curriculum``), the in-training evaluations (``learner.evaluation.stage_judge``),
TensorBoard's layout (``learner.run_log``), the progress displays and the job page read it.

A metric has one spelling, ``speed``, in three places that say where it comes from:

- training: the mean over the last N finished training episodes (sampled actions): the
  iteration's metric ``speed`` (TensorBoard ``train/speed``), a rule ``speed >= 1 over 100``;
- evaluation: the stage's deterministic evaluation (mean actions): the iteration's metric
  ``eval_speed`` (TensorBoard ``train/eval_speed``), a rule ``eval.speed >= 1``;
- a confirmation of an evaluation that promotes: ``confirmation_eval_speed``.

An evaluation report (``learner.evaluation.results.ModeResult``) keeps its own field names
with units (``mean_speed_m_s``): :attr:`EpisodeMetric.report_field` names it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

Aggregate = Literal["mean", "fraction"]
"""``mean``: the mean of the episodes' figures; ``fraction``: the share of episodes for which
it holds (a figure of 0 or 1 each)"""
EVALUATION_PREFIX = "eval."
"""a rule's metric with this prefix (``eval.fall_rate``) reads the stage's evaluation"""
EVALUATION_KEY = "eval_"
"""an iteration's metrics hold an evaluation's figures under this prefix (``eval_fall_rate``)"""
CONFIRMATION_KEY = "confirmation_"
"""and a confirmation's under this one before it (``confirmation_eval_fall_rate``)"""


@dataclass(frozen=True)
class Episode:
    """One finished episode as the metrics read it."""

    ret: float
    """return: the sum of its weighted reward terms"""
    distance: float
    """m: the pelvis's forward displacement"""
    length_s: float
    """s: simulated time"""
    fell: bool
    full: bool
    """it lasted the whole episode (``episode_s``)"""


@dataclass(frozen=True)
class EpisodeMetric:
    """One metric of episodes."""

    name: str
    unit: str
    """SI unit, ``""`` for a pure number or a fraction"""
    meaning: str
    aggregate: Aggregate
    of_episode: Callable[[Episode], float] | None
    """its figure for one training episode (None: measured on evaluations only)"""
    report_field: str
    """the field of an evaluation report (``ModeResult``) that holds it"""
    promotes: bool = True
    """a promotion rule may test it"""

    def evaluated(self, result: Any) -> float:
        """Its figure over an evaluation's episodes (``result``: a
        ``learner.evaluation.results.ModeResult``, which this module does not import: the
        evaluation package sits above the learner's core)."""
        value = getattr(result, self.report_field)
        return float(value.value if self.aggregate == "fraction" else value.mean)

    @property
    def label(self) -> str:
        """As a display or a plot names it, with its unit."""
        return f"{self.name} ({self.unit})" if self.unit else self.name


EPISODE_METRICS: tuple[EpisodeMetric, ...] = (
    EpisodeMetric(
        "return", "", "the sum of the weighted reward terms", "mean", lambda e: e.ret, "return_"
    ),
    EpisodeMetric(
        "distance",
        "m",
        "the pelvis's forward displacement, end minus start",
        "mean",
        lambda e: e.distance,
        "distance_m",
    ),
    EpisodeMetric(
        "speed",
        "m/s",
        "distance over the episode's time",
        "mean",
        lambda e: e.distance / max(e.length_s, 1e-9),
        "mean_speed_m_s",
    ),
    EpisodeMetric(
        "fall_rate",
        "",
        "episodes ended by a fall",
        "fraction",
        lambda e: float(e.fell),
        "fall_rate",
    ),
    EpisodeMetric(
        "survival",
        "",
        "episodes that lasted their whole length without a fall",
        "fraction",
        lambda e: float(e.full and not e.fell),
        "survival_rate",
    ),
    EpisodeMetric(
        "length", "s", "simulated time of the episode", "mean", lambda e: e.length_s, "time_s"
    ),
    EpisodeMetric(
        "turned",
        "deg",
        "size of the pelvis's turn about the vertical (a 3-D walker that turns loses distance)",
        "mean",
        None,
        "turned_deg",
        promotes=False,
    ),
)
BY_NAME = {metric.name: metric for metric in EPISODE_METRICS}
TRAINING_METRICS = tuple(m.name for m in EPISODE_METRICS if m.of_episode is not None)
"""the metrics of training episodes (an iteration's metrics hold each under its name)"""
RULE_METRICS = tuple(m.name for m in EPISODE_METRICS if m.promotes)
"""the metrics a promotion rule may test, on training episodes or (``eval.``) evaluations"""


def training_figure(name: str, episode: Episode) -> float:
    """Metric ``name``'s figure for one training episode."""
    of_episode = BY_NAME[name].of_episode
    assert of_episode is not None, f"{name} is measured on evaluations only"
    return of_episode(episode)


def evaluation_metrics(result: Any) -> dict[str, float]:
    """A deterministic evaluation (a ``ModeResult``) as an iteration's metrics: each metric's
    figure over the evaluation's episodes, keyed ``eval_<name>``."""
    return {EVALUATION_KEY + m.name: m.evaluated(result) for m in EPISODE_METRICS}


def evaluation_key(rule_metric: str) -> str:
    """The key of an evaluation rule's metric (``eval.fall_rate``) among an iteration's
    metrics (``eval_fall_rate``)."""
    return EVALUATION_KEY + rule_metric.removeprefix(EVALUATION_PREFIX)


def tensorboard_layout() -> dict[str, dict[str, list]]:
    """TensorBoard's custom-scalars layout: one chart per metric, its training and evaluation
    curves together (``train/<name>``, ``train/eval_<name>``), titled with its unit."""
    charts = {
        m.label: ["Multiline", [f"train/{m.name}", f"train/{EVALUATION_KEY}{m.name}"]]
        for m in EPISODE_METRICS
    }
    return {"episodes": charts}
