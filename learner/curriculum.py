"""Curriculum bookkeeping: whether a job's stages fit one policy lineage, where a run is in
its stages, the episodes behind each promotion rule, and the decision to move on.

The trainer feeds every fragment's finished episodes to :class:`CurriculumState`; after each
update it asks :meth:`CurriculumState.verdict` whether the stage is over (a
``learner.stage_verdict.StageVerdict``): its promotion rules
passed (each training rule over a full window of episodes, each evaluation rule on the
deterministic evaluation just run) or its env-step budget is spent. The state is plain data,
saved in each checkpoint's ``meta.json`` so that a resumed run keeps its window.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from gaitforge.learner.job import Job, PromotionRule, Stage
from gaitforge.learner.metrics import (
    EVALUATION_PREFIX,
    TRAINING_METRICS,
    Episode,
    evaluation_key,
    training_figure,
)
from gaitforge.learner.stage_verdict import GOES_ON, Outcome, RuleFigure, StageVerdict
from gaitforge.learner.symmetry import MirrorMap
from gaitforge.workers.fragment import Fragment
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.io_names import action_names, lateral_axis, observation_names
from gaitforge.workers.spec_io import SpecError

WINDOW_MAX = 10_000


class StageShortfallError(RuntimeError):
    """A stage with ``if_not_promoted: fail`` spent its budget before its promotion rules
    passed; the message names each rule, its figure and how far it fell short."""


class StageIO:
    """Observation and muscle names of a stage's scene on ``backend``, and its lateral axis,
    asked of the scene (``workers.scenes.io_names``): no env is built."""

    def __init__(self, scene: Scene, backend: str) -> None:
        self.obs_names: list[str] = observation_names(scene, backend)
        self.act_names: list[str] = action_names(scene, backend)
        self.lateral_axis = lateral_axis(scene.body)


def check_stages(job: Job, scenes: list[Scene]) -> tuple[list[StageIO], list[MirrorMap | None]]:
    """What the job file alone cannot tell: each ``optimize`` stage's scene has a reflex gait
    controller, and the stages' envs (``scenes``, resolved, one per stage) fit one policy
    lineage. Returns each stage's :class:`StageIO` and mirror map (None
    where the stage's ``ppo.mirror`` is off).

    Raises:
        SpecError: naming the stage (or ``ppo.mirror``) and what does not fit.
    """
    for i, (stage, scene) in enumerate(zip(job.stages, scenes, strict=True)):
        if stage.optimize is not None and not scene.action.gait:
            raise SpecError(
                f"stages.{i}.optimize: scene {scene.name!r} has action.kind "
                f"{scene.action.kind!r}; CMA-ES tunes a reflex_gait controller"
            )
    io = [StageIO(scene, job.stage_backend(i)) for i, scene in enumerate(scenes)]
    acts = io[0].act_names
    mirrors: list[MirrorMap | None] = []
    for i, stage_io in enumerate(io):
        if stage_io.act_names != acts:
            raise SpecError(f"stages.{i}: muscles differ from stage 0's; one job, one body")
        previous = io[i - 1].obs_names if i else stage_io.obs_names
        lost = [n for n in previous if n not in stage_io.obs_names]
        if lost:
            raise SpecError(f"stages.{i}: observations of stage {i - 1} missing: {lost[:4]}")
        if not job.stage_ppo(i).mirror:
            mirrors.append(None)
            continue
        try:
            mirrors.append(
                MirrorMap.from_names(stage_io.obs_names, stage_io.act_names, stage_io.lateral_axis)
            )
        except ValueError as exc:
            raise SpecError(f"ppo.mirror: stages.{i} ({scenes[i].name}): {exc}") from None
    return io, mirrors


def episodes_of(fragment: Fragment, scene: Scene) -> list[Episode]:
    """The episodes that ended in ``fragment`` (a rollout fragment of ``scene``)."""
    return [
        Episode(
            float(r),
            float(d),
            int(n) / scene.control_hz,
            bool(f),
            int(n) >= scene.steps_per_episode,
        )
        for r, d, n, f in zip(
            fragment.episode_return,
            fragment.episode_distance,
            fragment.episode_length,
            fragment.episode_fell,
            strict=True,
        )
    ]


@dataclass
class CurriculumState:
    """The stage a run is in, its env steps there, and its recent episodes."""

    stage: int = 0
    stage_env_steps: int = 0
    entered: bool = False
    """the stage's transition (scene push, new network) is done"""
    episodes: deque[Episode] = field(default_factory=lambda: deque(maxlen=WINDOW_MAX))
    evaluation: dict[str, float] = field(default_factory=dict)
    """the stage's last deterministic evaluation (``eval_*`` metrics, ``StageJudge.evaluate``);
    in memory only: empty before the stage's first evaluation, and after a resume until the
    next"""

    def add(self, fragment: Fragment, scene: Scene) -> None:
        self.stage_env_steps += fragment.steps
        self.episodes.extend(episodes_of(fragment, scene))

    def window_mean(self, metric: str, window: int) -> float:
        """Mean of ``metric`` over the last ``window`` episodes (NaN with none); for an
        evaluation metric (``eval.fall_rate``), the stage's last evaluation's (NaN before
        one)."""
        if metric.startswith(EVALUATION_PREFIX):
            return self.evaluation.get(evaluation_key(metric), float("nan"))
        recent = list(self.episodes)[-window:]
        figures = [training_figure(metric, e) for e in recent]
        return float(np.mean(figures)) if recent else float("nan")

    def summary(self, window: int = 100) -> dict[str, float]:
        """Every metric's mean over the last ``window`` episodes."""
        return {m: self.window_mean(m, window) for m in TRAINING_METRICS}

    def verdict(self, stage: Stage, evaluation: dict[str, float] | None = None) -> StageVerdict:
        """Whether the stage ends now, on its figures: promoted when all the stage's rules
        pass (each training rule on the mean over its window of episodes, once the window is
        full; each evaluation rule, ``eval.*``, on ``evaluation``, the ``eval_*`` metrics of
        the stage's deterministic evaluation just run, None where none ran now: a stage with
        evaluation rules promotes only at an evaluation); else its budget spent once its env
        steps reach it; else it goes on. A stage that fails is told apart by its judge
        (``learner.evaluation.training_hooks.StageJudging.decide``), which names the
        shortfall."""
        rules = stage.promote
        figures = self._figures(rules, evaluation)
        if figures is not None and all(
            rule.passes(f) for rule, f in zip(rules, figures, strict=True)
        ):
            return StageVerdict(
                Outcome.PROMOTED,
                tuple(RuleFigure(rule, f) for rule, f in zip(rules, figures, strict=True)),
            )
        if self.stage_env_steps >= stage.env_steps:
            return StageVerdict(Outcome.BUDGET_SPENT)
        return GOES_ON

    def shortfall(self, stage: Stage, name: str, evaluation: dict[str, float]) -> str:
        """Why stage ``name`` ended unpromoted, in one line: each rule with its figure (a
        training rule over its window, an evaluation rule on ``evaluation``, the ``eval_*``
        metrics of the network the stage ends with) and, where it failed, by how much."""
        parts = []
        for rule in stage.promote:
            if rule.on_evaluation:
                figure = evaluation.get(evaluation_key(rule.metric), float("nan"))
            else:
                figure = self.window_mean(rule.metric, rule.window)
            if np.isnan(figure):
                parts.append(f"{rule.metric}: not measured (no {_source(rule)})")
            elif rule.passes(figure):
                parts.append(f"{rule.metric} {figure:.3g} {rule.op} {rule.value:g}: passed")
            else:
                gap = abs(figure - rule.value)
                parts.append(
                    f"{rule.metric} {figure:.3g}, not {rule.op} {rule.value:g} (short by {gap:.3g})"
                )
        return (
            f"stage {self.stage} ({name}) spent its {stage.env_steps:,} env steps without "
            f"reaching its target: {'; '.join(parts)}"
        )

    def _figures(
        self, rules: list[PromotionRule], evaluation: dict[str, float] | None
    ) -> list[float] | None:
        """Each rule's figure, or None if not every rule can be judged now (none at all, a
        training window not yet full, an evaluation rule and no evaluation)."""
        if not rules:
            return None
        figures = []
        for rule in rules:
            if rule.on_evaluation:
                if evaluation is None:
                    return None
                figures.append(evaluation[evaluation_key(rule.metric)])
            elif len(self.episodes) < rule.window:
                return None
            else:
                figures.append(self.window_mean(rule.metric, rule.window))
        return figures

    def advance(self) -> None:
        self.stage += 1
        self.stage_env_steps = 0
        self.entered = False
        self.episodes.clear()
        self.evaluation = {}

    def to_json(self) -> dict:
        return {
            "stage": self.stage,
            "stage_env_steps": self.stage_env_steps,
            "entered": self.entered,
            "episodes": [
                [e.ret, e.distance, e.length_s, e.fell, e.full] for e in list(self.episodes)[-1000:]
            ],
        }

    @classmethod
    def from_json(cls, raw: dict) -> CurriculumState:
        state = cls(int(raw["stage"]), int(raw["stage_env_steps"]), bool(raw["entered"]))
        state.episodes.extend(Episode(*e) for e in raw["episodes"])
        return state


def _source(rule: PromotionRule) -> str:
    """What a rule's figure comes from, for a message that it has none."""
    return "evaluation" if rule.on_evaluation else "finished training episode"
