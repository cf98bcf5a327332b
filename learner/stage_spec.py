"""A job's stages as its file writes them: the scene and budget of each, promotion rules,
the network and the transition that builds it, blending, in-training evaluations and the
stage's own PPO schedules (``learner.job`` holds the job around them)."""

from __future__ import annotations

import json
import re
from typing import Annotated, Any, Literal

from gaitforge.learner.metrics import EVALUATION_PREFIX, RULE_METRICS
from gaitforge.learner.ppo import EntropyWeight, LearningRate
from gaitforge.workers.gait_measure import GaitMeasure
from gaitforge.workers.spec_types import MAX_NAME_LENGTH, SPEC_VALUES, Name, Ref
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    field_validator,
    model_serializer,
    model_validator,
)

METRICS = RULE_METRICS
"""Episode metrics a promotion rule can test (``learner.metrics``: each averaged over its
episodes): return; distance (m); speed (m/s); fall rate; survival; length (s)."""
EVALUATION_METRICS = tuple(EVALUATION_PREFIX + metric for metric in METRICS)
RuleMetric = Literal[(*METRICS, *EVALUATION_METRICS)]  # type: ignore[valid-type]
"""a rule's metric: a training metric, or an evaluation's (``eval.<metric>``)"""
DEFAULT_WINDOW = 100
"""training episodes a rule's mean is over when it names none"""

MAX_RULE_LENGTH = 200
"""the longest promotion rule written as a string"""
_RULE = re.compile(
    r"^\s*(?P<metric>(?:eval\.)?[a-z_]+)\s*(?P<op>>=|<=)\s*(?P<value>[-+0-9.eE]+)\s*"
    r"(?:over\s+(?P<window>\d+))?\s*$"
)


MAX_PROMOTION_RULES = 16
"""the most promotion rules one stage may have"""
MAX_SCENE_SET = 64
"""the most scene fields one stage may set"""
SCENE_FIELDS_OF_OLD = ("fidelity", "control_hz", "action")
"""scene fields older job files set on a stage itself, now keys of its ``scene_set``"""


class StrictSpec(BaseModel):
    """A part of a job file: unknown fields are errors, values are frozen, numbers strict and
    finite (``workers.spec_types.SPEC_VALUES``: no ``"1000"`` or ``true`` for an int)."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)


class PromotionRule(StrictSpec):
    """Promote when ``metric`` passes ``value``. Written as a mapping or a string:
    ``"distance >= 5 over 100"``, ``"eval.fall_rate <= 0.1"``.

    A training metric (``distance``) is the mean over the last ``window`` training episodes
    (sampled actions), judged after every update once that many episodes have finished. An
    evaluation metric (``eval.distance``) is the stage's deterministic evaluation
    (``evaluate:``, which the stage must have): the mean policy over the evaluation's
    ``evaluate.episodes`` episodes, judged at each evaluation; it takes no ``over
    <episodes>``, since the evaluation's episodes are its window. A stage's rules must all
    pass at once, so a stage with an evaluation rule promotes only at an evaluation.
    """

    metric: RuleMetric
    op: Literal[">=", "<="]
    value: float
    window: Annotated[int, Field(ge=1, le=10_000)] = DEFAULT_WINDOW
    """training episodes the mean is over (training metrics only)"""

    @property
    def on_evaluation(self) -> bool:
        """The rule reads the stage's deterministic evaluation (an ``eval.`` metric)."""
        return self.metric.startswith(EVALUATION_PREFIX)

    @property
    def statistic(self) -> str:
        """The episode statistic tested: ``metric`` without ``eval.`` (one of ``METRICS``)."""
        return self.metric.removeprefix(EVALUATION_PREFIX)

    @model_validator(mode="after")
    def _no_window_on_evaluation(self) -> PromotionRule:
        if self.on_evaluation and "window" in self.model_fields_set:
            raise ValueError(_NO_WINDOW.format(metric=self.metric))
        return self

    @model_serializer(mode="wrap")
    def _without_unused_window(self, handler: SerializerFunctionWrapHandler):
        """An evaluation rule is written without the window it does not use (and so reads
        back). No return annotation: pydantic then keeps the model's own JSON schema for
        serialization (a ``dict`` one would make it any object)."""
        fields = handler(self)
        if self.on_evaluation:
            fields.pop("window", None)
        return fields

    def __str__(self) -> str:
        if self.on_evaluation:
            return f"{self.metric} {self.op} {self.value:g} on the stage's evaluation"
        return f"{self.metric} {self.op} {self.value:g} over {self.window} episodes"

    def passes(self, mean: float) -> bool:
        return mean >= self.value if self.op == ">=" else mean <= self.value


_NO_WINDOW = (
    "{metric}: no 'over <episodes>' for an evaluation rule: it reads the whole of the stage's "
    "evaluation (evaluate.episodes episodes)"
)


def _parse_rule(raw: object) -> object:
    """``"distance >= 5 over 100"`` -> its fields (the value a float, the window an int);
    a mapping passes through."""
    if not isinstance(raw, str):
        return raw
    match = _RULE.match(raw) if len(raw) <= MAX_RULE_LENGTH else None
    if match is None:
        raise ValueError(
            f"expected '<metric> >=|<= <value> [over <episodes>]' (at most {MAX_RULE_LENGTH} "
            f"characters), metric one of {METRICS} or of the stage's evaluation, "
            f"{EVALUATION_PREFIX}<metric> (no 'over')"
        )
    if match["metric"].startswith(EVALUATION_PREFIX) and match["window"] is not None:
        raise ValueError(_NO_WINDOW.format(metric=match["metric"]))
    fields: dict[str, object] = {"metric": match["metric"], "op": match["op"]}
    try:
        fields["value"] = float(match["value"])
    except ValueError:
        raise ValueError(f"{match['value']!r} is not a number") from None
    if match["window"] is not None:
        fields["window"] = int(match["window"])
    return fields


class NetworkSpec(StrictSpec):
    hidden: list[Annotated[int, Field(ge=1, le=4096)]] = Field(
        default_factory=lambda: [64, 64], min_length=1, max_length=8
    )
    init_std: Annotated[float, Field(gt=0, le=2)] = 0.3
    """initial standard deviation of the excitations"""


class BlendSpec(StrictSpec):
    ramp_env_steps: Annotated[int, Field(ge=1)] = 200_000
    """alpha goes linearly from 0 to 1 over this many env steps of the stage"""
    critic_warmup_env_steps: Annotated[int, Field(ge=0)] = 8192
    """env steps of pi_old's rollouts the new critic is fitted to before alpha ramps"""
    fit_epochs: Annotated[int, Field(ge=1, le=1000)] = 50
    """passes of the fit over that data"""


class StageEvaluation(StrictSpec):
    """Deterministic evaluations during a stage (``learner.evaluation.stage_judge``): the stage is
    judged on an evaluation scene as ``gaitforge evaluate`` would judge it, not only on its
    training episodes (stochastic actions, and a training scene's mixed starts, hide how the
    mean policy does from standing)."""

    scene: Ref | None = None
    """catalogue scene or scene YAML path (relative to the job file) with the stage's
    observations and muscles: the plain scene an imitation or curriculum scene stands in for
    (e.g. ``run-2d+clock`` for ``imitate-run-2d+standing-starts``), with the stage's
    ``scene_set`` (its fidelity, control-rate and action overrides are not applied); None:
    the stage's own scene as trained"""
    episodes: Annotated[int, Field(ge=1, le=10_000)] = 50
    """episodes per evaluation (seeds ``EVALUATION_SEED`` + i, the same at every evaluation),
    and per confirmation of an evaluation that promotes (fresh seeds each time)"""
    every_env_steps: Annotated[int, Field(ge=1)] = 200_000
    """env steps of the stage between evaluations (the first follows its first update, the
    last its end)"""
    keep_best: bool = True
    """end the stage with the best network evaluated (the most promotion rules passed on the
    evaluation, then the fewest falls, then the highest return) instead of the last"""


class StagePPO(StrictSpec):
    """A stage's own PPO schedules and batch, in place of the job's ``ppo`` ones (each field
    left out keeps the job's): fine-tuning a trained policy at a lower learning rate, or a
    stage on a slower simulator with smaller batches, for example."""

    batch_env_steps: Annotated[int, Field(ge=1)] | None = None
    """env steps gathered per update in this stage (``learner.ppo.PPOSettings.batch_env_steps``)"""
    minibatch_size: Annotated[int, Field(ge=1)] | None = None
    """samples per minibatch in this stage (``learner.ppo.PPOSettings.minibatch_size``)"""
    lr: LearningRate | None = None
    """Adam learning rate at the stage's start"""
    lr_end: LearningRate | None = None
    """learning rate at the stage's end (linear schedule)"""
    critic_lr: LearningRate | None = None
    """the critic's own learning rate over the stage (``learner.ppo.PPOSettings.critic_lr``)"""
    mirror: bool | None = None
    """mirror augmentation in this stage (``learner.ppo.PPOSettings.mirror``): a fine-tune
    of a policy with little action noise may do without it"""
    decoupled: bool | None = None
    """PPO's decoupled objective in this stage (``learner.ppo.PPOSettings.decoupled``)"""
    entropy_coef: EntropyWeight | None = None
    """entropy weight at the stage's start"""
    entropy_coef_end: EntropyWeight | None = None
    """entropy weight at the stage's end (linear schedule)"""


class StageOptimize(StrictSpec):
    """A stage that tunes its scene's reflex gait controller (``action.kind: reflex_gait``)
    with CMA-ES instead of training the network (``learner.cmaes``): each iteration is one
    generation, scored on the rollout actors."""

    method: Literal["cmaes"] = "cmaes"
    population: Annotated[int, Field(ge=2, le=1024)] = 16
    generations: Annotated[int, Field(ge=1, le=100_000)] = 200
    minutes: Annotated[float, Field(gt=0)] | None = Field(
        default=None, description="end the stage after this much wall-clock time of it"
    )
    sigma: Annotated[float, Field(gt=0, le=0.5)] = Field(
        default=0.1, description="initial step, as a share of each parameter's range"
    )
    episodes: Annotated[int, Field(ge=1, le=100)] = Field(
        default=3, description="episodes per candidate, each from its own noisy start"
    )
    measure: GaitMeasure = GaitMeasure()


class Stage(StrictSpec):
    """One curriculum stage: a scene, a budget and a rule to leave early."""

    scene: Ref
    """a catalogue scene (``base`` or ``base+option+...``) or a scene YAML path (relative to
    the job file)"""
    scene_set: dict[Annotated[str, Field(max_length=MAX_NAME_LENGTH)], Any] = Field(
        default_factory=dict, max_length=MAX_SCENE_SET
    )
    """scene fields set by dotted path, on the stage's scene and on its evaluation scene: the
    one way a stage changes its scene (``{task.target_speed: 2.5}``; ``{control_hz: 25}``,
    a lower rate repeating each action over more simulator steps, the 2017 entrants' frame
    skip; ``{fidelity: fast}``, a fidelity curriculum; ``{action: {kind: joint_targets}}``,
    joint targets through a reflex layer instead of excitations)"""
    name: Name | None = None
    """defaults to the scene's name"""
    backend: Literal["mujoco", "opensim"] | None = None
    """the stage's simulator (default: the job's ``backend``): train fast on MuJoCo, then
    finish on OpenSim in a later stage"""
    env_steps: Annotated[int, Field(ge=1)]
    """the stage's budget; it ends at the budget even if the rule never passed"""
    promote: list[PromotionRule] = Field(default_factory=list, max_length=MAX_PROMOTION_RULES)
    """rules that must all pass to promote early; one rule may be given alone"""
    if_not_promoted: Literal["next", "fail"] = "next"
    """when the budget is spent before the rules pass: go on to the next stage, or end the
    job (``fail``), naming each rule that fell short and by how much (the checkpoint of the
    stage's end is written first)"""
    network: NetworkSpec | None = None
    """a new network for this stage (needs a building transition); None keeps the current"""
    transition: Literal["continue", "blend"] = "continue"
    """``continue``: the network goes on (widened with zero weights where the stage
    observes more); ``blend``: a new ``network`` is blended in from the current one
    (policy blending: alpha ramps 0 -> 1 over ``blend.ramp_env_steps``)"""
    blend: BlendSpec = BlendSpec()
    evaluate: StageEvaluation | None = None
    """deterministic evaluations on a scene during the stage, and the best network kept at
    its end; None: none"""
    ppo: StagePPO = StagePPO()
    """the stage's learning-rate and entropy schedules, where they differ from the job's"""
    optimize: StageOptimize | None = None
    """tune the scene's reflex gait controller with CMA-ES in this stage (its budget is
    ``env_steps`` and the generations); the tuned parameters go on to the later stages whose
    scenes use the same controller (PPO on top); None: a PPO stage"""
    action_std: Annotated[float, Field(gt=0, le=1)] | None = None
    """with transition ``continue``: the action noise's standard deviation (action units)
    the network starts the stage with, in place of the one the stage before (or, in the
    first stage, the job's ``init_from`` checkpoint) trained it down to (a stage that must
    learn something new explores again); None keeps it"""

    @model_validator(mode="before")
    @classmethod
    def _scene_fields_in_scene_set(cls, raw: object) -> object:
        """A scene field written on the stage itself is named with where it goes."""
        if isinstance(raw, dict):
            for name in SCENE_FIELDS_OF_OLD:
                if name in raw:
                    value = json.dumps(raw[name], default=str)
                    raise ValueError(
                        f"{name}: a scene field; set it in the stage's scene_set "
                        f"(scene_set: {{{name}: {value}}})"
                    )
        return raw

    @field_validator("promote", mode="before")
    @classmethod
    def _parse_rules(cls, raw: object) -> object:
        rules = raw if isinstance(raw, list) else [] if raw is None else [raw]
        return [_parse_rule(rule) for rule in rules]

    @model_validator(mode="after")
    def _failing_needs_rules(self) -> Stage:
        if self.if_not_promoted == "fail" and not self.promote:
            raise ValueError(
                "if_not_promoted: fail needs promote: rules, the target the stage must reach"
            )
        return self

    @model_validator(mode="after")
    def _evaluation_rules_evaluated(self) -> Stage:
        on_evaluation = [rule.metric for rule in self.promote if rule.on_evaluation]
        if on_evaluation and self.evaluate is None:
            raise ValueError(
                f"promote: {on_evaluation[0]} reads the stage's deterministic evaluation; "
                "the stage needs evaluate: (e.g. evaluate: {episodes: 50})"
            )
        return self

    @model_validator(mode="after")
    def _optimize_alone(self) -> Stage:
        if self.optimize is None:
            return self
        used = [
            name
            for name, on in (
                ("promote", bool(self.promote)),
                ("evaluate", self.evaluate is not None),
                ("network", self.network is not None),
                ("transition", self.transition != "continue"),
                ("action_std", self.action_std is not None),
            )
            if on
        ]
        if used:
            raise ValueError(
                f"optimize: a CMA-ES stage trains no network; {used} are for PPO stages"
            )
        return self

    @model_validator(mode="after")
    def _transition_fits(self) -> Stage:
        if self.network is not None and self.transition == "continue":
            raise ValueError("network: a new network needs transition blend (not continue)")
        if self.action_std is not None and self.transition != "continue":
            raise ValueError(
                "action_std: only with transition continue (a new network starts at its "
                "network's init_std)"
            )
        return self
