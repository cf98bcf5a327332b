"""The job file: a body's curriculum of stages, PPO settings, workers and checkpoints.

Validated once, early (``load_job``): every scene must load, each stage's scene must run on
the job's backend, and a network change between stages needs a transition that builds a new
network (``blend``, ``distil`` or ``scratch``). Errors are one line naming the file and field.

    name: walk-2d
    backend: mujoco
    network: {hidden: [64, 64]}
    ppo: {batch_env_steps: 8192, lr: 3.0e-4, lr_end: 1.0e-4, entropy_coef: 0.001}
    stages:
      - scene: stand-2d
        env_steps: 300000
        promote: "survival >= 0.95 over 50"     # or a list of rules that must all pass
      - scene: walk-2d
        env_steps: 2000000
        network: {hidden: [128, 128]}
        transition: blend
        blend: {ramp_env_steps: 200000}

An imitation stage may start from the motion's recorded muscle excitations, cloned into the
actor's mean (``warm_start: {excitations: walk}``, :class:`WarmStartSpec`).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Literal

from gaitforge.learner.ppo import EntropyWeight, LearningRate, PPOSettings
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.action import ActionSpec
from gaitforge.workers.scenes.profiles import Fidelity
from gaitforge.workers.spec_io import SpecError, format_validation_error, load_yaml_model
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

METRICS = ("return", "distance", "speed", "fall_rate", "survival", "length")
"""Episode statistics a promotion rule can test, each averaged over its window: return;
distance covered (m); mean speed (m/s); fall rate (fraction of episodes that fell);
survival (fraction that lasted the whole episode without falling); length (s)."""

_RULE = re.compile(
    r"^\s*(?P<metric>[a-z_]+)\s*(?P<op>>=|<=)\s*(?P<value>[-+0-9.eE]+)\s*"
    r"(?:over\s+(?P<window>\d+))?\s*$"
)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PromotionRule(_Strict):
    """Promote when the mean of ``metric`` over the last ``window`` episodes passes
    ``value``. Written as a mapping or a string: ``"distance >= 5 over 100"``."""

    metric: Literal["return", "distance", "speed", "fall_rate", "survival", "length"]
    op: Literal[">=", "<="]
    value: float
    window: Annotated[int, Field(ge=1, le=10_000)] = 100

    def __str__(self) -> str:
        return f"{self.metric} {self.op} {self.value:g} over {self.window} episodes"

    def passes(self, mean: float) -> bool:
        return mean >= self.value if self.op == ">=" else mean <= self.value


def _parse_rule(raw: object) -> object:
    """``"distance >= 5 over 100"`` -> its fields; a mapping passes through."""
    if not isinstance(raw, str):
        return raw
    match = _RULE.match(raw)
    if match is None:
        raise ValueError(
            f"expected '<metric> >=|<= <value> [over <episodes>]', metric one of {METRICS}"
        )
    return {k: v for k, v in match.groupdict().items() if v is not None}


class NetworkSpec(_Strict):
    hidden: list[Annotated[int, Field(ge=1, le=4096)]] = Field(
        default_factory=lambda: [64, 64], min_length=1, max_length=8
    )
    init_std: Annotated[float, Field(gt=0, le=2)] = 0.3
    """initial standard deviation of the excitations"""


class BlendSpec(_Strict):
    ramp_env_steps: Annotated[int, Field(ge=1)] = 200_000
    """alpha goes linearly from 0 to 1 over this many env steps of the stage"""
    critic_warmup_env_steps: Annotated[int, Field(ge=0)] = 8192
    """env steps of pi_old's rollouts the new critic (and, for distil, actor) is fitted to"""
    fit_epochs: Annotated[int, Field(ge=1, le=1000)] = 50
    """passes of the fit over that data"""
    clone_actor: bool = False
    """``blend`` only: fit pi_new's actor to pi_old's actions too (as ``distil`` does)
    before alpha ramps, so that the blend moves from pi_old towards its clone rather than
    towards an untrained network"""


class WarmStartSpec(_Strict):
    """Before PPO, fit the actor's mean excitation to a motion's recorded (CMC) excitations
    as a function of the gait phase in the observation (behavioural cloning,
    ``learner.clone_excitations``): roll out in the stage's imitation scene (episodes start
    inside the motion), label each observation with the excitations at its phase, fit the
    mean by squared error; then roll out the fitted policy and fit again (``rounds``)."""

    excitations: str
    """the motion whose recorded excitations are cloned (e.g. ``walk``): the motion the
    stage's scene imitates (``task.imitate.motion``), whose phase it observes"""
    env_steps: Annotated[int, Field(ge=1)] = 8192
    """env steps of rollouts per round (they count in the stage's env steps)"""
    rounds: Annotated[int, Field(ge=1, le=10)] = 2
    """rollout-and-fit rounds: the first rolls out the initial policy, the next ones the
    policy fitted so far (DAgger-like), on all the observations gathered"""
    epochs: Annotated[int, Field(ge=1, le=1000)] = 30
    """passes of each fit over the observations"""
    lr: Annotated[float, Field(gt=0, le=1)] = 1e-3


class StageEvaluation(_Strict):
    """Deterministic evaluations during a stage (``learner.stage_judge``): the stage is
    judged on an evaluation scene as ``gaitforge evaluate`` would judge it, not only on its
    training episodes (stochastic actions, and a training scene's mixed starts, hide how the
    mean policy does from standing)."""

    scene: str | None = None
    """catalogue name or scene YAML path (relative to the job file) with the stage's
    observations and muscles: the plain catalogue scene an imitation or curriculum scene
    stands in for (e.g. ``run-2d-clock`` for ``imitate-run-2d-start``), as it is (the
    stage's fidelity, control-rate and action overrides are not applied); None: the stage's
    own scene as trained"""
    episodes: Annotated[int, Field(ge=1, le=10_000)] = 50
    """episodes per evaluation (seeds ``EVALUATION_SEED`` + i, the same at every evaluation)"""
    every_env_steps: Annotated[int, Field(ge=1)] = 200_000
    """env steps of the stage between evaluations (the first follows its first update, the
    last its end)"""
    keep_best: bool = True
    """end the stage with the best network evaluated (the most promotion rules passed on the
    evaluation, then the fewest falls, then the highest return) instead of the last"""


class StagePPO(_Strict):
    """A stage's own PPO schedules, in place of the job's ``ppo`` ones (each field left out
    keeps the job's): fine-tuning a trained policy at a lower learning rate, for example."""

    lr: LearningRate | None = None
    """Adam learning rate at the stage's start"""
    lr_end: LearningRate | None = None
    """learning rate at the stage's end (linear schedule)"""
    entropy_coef: EntropyWeight | None = None
    """entropy weight at the stage's start"""
    entropy_coef_end: EntropyWeight | None = None
    """entropy weight at the stage's end (linear schedule)"""


class Stage(_Strict):
    """One curriculum stage: a scene, a budget and a rule to leave early."""

    scene: str
    """catalogue name or scene YAML path (relative to the job file)"""
    name: str | None = None
    """defaults to the scene's name"""
    backend: Literal["mujoco", "opensim"] | None = None
    """the stage's simulator (default: the job's ``backend``): train fast on MuJoCo, then
    finish on OpenSim in a later stage"""
    fidelity: Fidelity | None = None
    """overrides the scene's fidelity profile (a fidelity curriculum changes only this)"""
    control_hz: Annotated[float, Field(gt=0, le=1000)] | None = None
    """overrides the scene's control rate: a lower rate repeats each action over more
    simulator steps (the 2017 entrants' frame skip), which shortens the credit horizon"""
    action: ActionSpec | None = None
    """overrides the scene's action space (``workers.scenes.action``): joint targets through
    a reflex layer instead of excitations"""
    env_steps: Annotated[int, Field(ge=1)]
    """the stage's budget; it ends at the budget even if the rule never passed"""
    promote: list[PromotionRule] = Field(default_factory=list)
    """rules that must all pass to promote early; one rule may be given alone"""
    network: NetworkSpec | None = None
    """a new network for this stage (needs a building transition); None keeps the current"""
    transition: Literal["continue", "blend", "distil", "scratch"] = "continue"
    blend: BlendSpec = BlendSpec()
    warm_start: WarmStartSpec | None = None
    """clone a motion's recorded excitations into the actor's mean when the stage starts
    (after its transition); None: no warm start"""
    evaluate: StageEvaluation | None = None
    """deterministic evaluations on a scene during the stage, and the best network kept at
    its end; None: none"""
    ppo: StagePPO = StagePPO()
    """the stage's learning-rate and entropy schedules, where they differ from the job's"""
    action_std: Annotated[float, Field(gt=0, le=1)] | None = None
    """with transition ``continue``: the action noise's standard deviation (action units)
    the network starts the stage with, in place of the one the stage before trained it down
    to (a stage that must learn something new explores again); None keeps it"""

    @field_validator("promote", mode="before")
    @classmethod
    def _parse_rules(cls, raw: object) -> object:
        rules = raw if isinstance(raw, list) else [] if raw is None else [raw]
        return [_parse_rule(rule) for rule in rules]

    @model_validator(mode="after")
    def _transition_fits(self) -> Stage:
        if self.network is not None and self.transition == "continue":
            raise ValueError(
                "network: a new network needs transition blend, distil or scratch (not continue)"
            )
        if self.action_std is not None and self.transition != "continue":
            raise ValueError(
                "action_std: only with transition continue (a new network starts at its "
                "network's init_std)"
            )
        if self.blend.clone_actor and self.transition != "blend":
            raise ValueError(
                "blend.clone_actor: only with transition blend (distil always clones the actor)"
            )
        if self.warm_start is not None and self.transition == "blend":
            raise ValueError(
                "warm_start: not with transition blend (pi_old acts at first); use distil, "
                "scratch or continue"
            )
        return self


class WorkersSpec(_Strict):
    num_workers: Annotated[int, Field(ge=0, le=4096)] | None = None
    """Ray rollout actors (None: the cluster's CPUs less one; 0: one in-process worker)"""
    envs_per_worker: Annotated[int, Field(ge=1, le=1024)] = 8
    fragment_length: Annotated[int, Field(ge=8, le=100_000)] = 128
    ray_address: str | None = None
    """a Ray cluster to join ("auto", "ray://host:10001"); None: start a local one"""
    timeout_s: Annotated[float, Field(gt=0)] = 600.0
    """an actor with no fragment for this long is replaced"""


class CheckpointSpec(_Strict):
    every_iters: Annotated[int, Field(ge=1)] = 10
    keep_last: Annotated[int, Field(ge=1)] = 3
    record_every_iters: Annotated[int, Field(ge=0)] = 0
    """an MCAP recording of one deterministic episode every N iterations (0: at stage ends
    only)"""


class Job(_Strict):
    """A training job: the first network, PPO, workers, checkpoints and the stages."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
    backend: Literal["mujoco", "opensim"] = "mujoco"
    seed: int = 0
    network: NetworkSpec = NetworkSpec()
    ppo: PPOSettings = PPOSettings()
    """PPO settings and schedules (``learner.ppo.PPOSettings``)"""
    workers: WorkersSpec = WorkersSpec()
    checkpoint: CheckpointSpec = CheckpointSpec()
    init_from: str | None = None
    """a checkpoint directory (relative to the job file) whose network and observation
    statistics start the first stage, for fine-tuning a trained policy on another scene or
    backend (the optimizer, curriculum and env-step count start afresh); e.g.
    ``examples/policies/walk-2d``. The first stage may then grow a new network from it
    (``transition: blend``, ``distil`` or ``scratch`` with its own ``network``), as a later
    stage grows one from the stage before"""
    init_from_action_std: Annotated[float, Field(gt=0, le=1)] | None = None
    """with ``init_from``: the action noise's standard deviation (action units) the loaded
    network starts with, in place of the one it was trained down to (a fine-tune that must
    learn something new explores again); None keeps the checkpoint's"""
    stages: list[Stage] = Field(min_length=1)

    def stage_backend(self, index: int) -> str:
        """The simulator of stage ``index``: its own ``backend``, else the job's."""
        return self.stages[index].backend or self.backend

    def stage_ppo(self, index: int) -> PPOSettings:
        """The PPO settings of stage ``index``: the job's, with the stage's own schedules."""
        return self.ppo.model_copy(update=self.stages[index].ppo.model_dump(exclude_none=True))

    @model_validator(mode="after")
    def _first_stage(self) -> Job:
        first = self.stages[0]
        if (first.transition != "continue" or first.network is not None) and not self.init_from:
            raise ValueError(
                "stages.0: the first stage uses the job's network (no transition); a transition "
                "(blend, distil, scratch) there needs init_from, the network it starts from"
            )
        if first.action_std is not None:
            raise ValueError(
                "stages.0.action_std: the first stage starts at network.init_std, or with "
                "init_from at init_from_action_std"
            )
        if self.init_from_action_std is not None and self.init_from is None:
            raise ValueError("init_from_action_std: only with init_from (a network to reset)")
        return self


def load_job(path: Path) -> tuple[Job, list[Scene]]:
    """Read and check a job file; returns the job and each stage's resolved scene (with the
    stage's fidelity override applied).

    Raises:
        SpecError: one line naming the file, the field and what is allowed.
    """
    job = load_yaml_model(path, Job)
    if job.init_from is not None:
        start = (path.parent / job.init_from).resolve()
        if not (start / "meta.json").is_file():
            raise SpecError(
                f"{path}: init_from: {job.init_from!r}: no checkpoint there (a directory with "
                "meta.json and policy.safetensors, as the trainer writes them)"
            )
        job = job.model_copy(update={"init_from": str(start)})
    job = _with_evaluation_paths(job, path.parent)
    return job, resolve_scenes(job, base=path.parent, source=str(path))


def _with_evaluation_paths(job: Job, base: Path) -> Job:
    """``job`` with each stage's ``evaluate.scene`` YAML path made absolute (relative to the
    job file's directory ``base``), so the trainer finds it from any working directory."""
    stages = []
    for stage in job.stages:
        ref = stage.evaluate.scene if stage.evaluate is not None else None
        if ref and ref.endswith((".yaml", ".yml")) and not Path(ref).is_absolute():
            spec = stage.evaluate.model_copy(update={"scene": str((base / ref).resolve())})
            stage = stage.model_copy(update={"evaluate": spec})
        stages.append(stage)
    return job.model_copy(update={"stages": stages})


def resolve_scenes(job: Job, base: Path = Path("."), source: str = "job") -> list[Scene]:
    """Each stage's scene, checked against the job's backend and resolved on this machine
    (``Scene.resolved``: named, saved and ``auto`` fidelity profiles become concrete ones),
    so that actors on any node and the checkpoints get the profile chosen here."""
    scenes = []
    for i, stage in enumerate(job.stages):
        ref = stage.scene
        if ref.endswith((".yaml", ".yml")) and not Path(ref).is_absolute():
            ref = str(base / ref)
        try:
            scene = load_scene(ref)
        except SpecError as exc:
            raise SpecError(f"{source}: stages.{i}.scene: {exc}") from None
        backend = job.stage_backend(i)
        if backend not in scene.backends:
            whose = f"stages.{i}.backend" if stage.backend else "the job's backend"
            raise SpecError(
                f"{source}: stages.{i}.scene: {scene.name!r} runs on {scene.backends}, "
                f"not on {whose} {backend!r}"
            )
        overrides = {k: v for k in ("fidelity", "control_hz", "action") if (v := getattr(stage, k))}
        if overrides or stage.backend:  # checked on the stage's backend only
            raw = {**scene.model_dump(), **overrides, "backends": [backend]}
            try:
                scene = Scene.model_validate(raw)
            except ValidationError as err:
                message = format_validation_error(f"{source}: stages.{i}", err)
                raise SpecError(message.replace(": <root>:", ":")) from None
        try:
            scenes.append(scene.resolved())
        except ValueError as exc:
            raise SpecError(f"{source}: stages.{i}.scene: {exc}") from None
        if stage.warm_start is not None:
            check_warm_start(scenes[-1], stage.warm_start, f"{source}: stages.{i}.warm_start")
        if stage.evaluate is not None and (ref := stage.evaluate.scene) is not None:
            if ref.endswith((".yaml", ".yml")) and not Path(ref).is_absolute():
                ref = str(base / ref)
            evaluation_scene(ref, backend, f"{source}: stages.{i}.evaluate.scene")
    return scenes


def evaluation_scene(ref: str, backend: str, where: str) -> Scene:
    """A stage's evaluation scene (``evaluate.scene``), loaded and resolved for ``backend``.

    Raises:
        SpecError: ``where`` (file and field): the scene does not load or runs elsewhere.
    """
    try:
        scene = load_scene(ref)
    except SpecError as exc:
        raise SpecError(f"{where}: {exc}") from None
    if backend not in scene.backends:
        raise SpecError(f"{where}: {scene.name!r} runs on {scene.backends}, not on {backend!r}")
    try:
        return scene.resolved()
    except ValueError as exc:
        raise SpecError(f"{where}: {exc}") from None


def check_warm_start(scene: Scene, spec: WarmStartSpec, where: str) -> None:
    """The stage's scene imitates a motion (it observes the phase) and the body has recorded
    excitations for ``spec.excitations``.

    Raises:
        SpecError: ``where`` (file and field), what is wrong and what is allowed.
    """
    from gaitforge.learner.clone_excitations import ExcitationError, excitation_table

    imitate = getattr(scene.task, "imitate", None)
    if imitate is None:
        raise SpecError(
            f"{where}: scene {scene.name!r} imitates no motion (task.imitate); a warm start "
            "from recorded excitations needs an imitation scene (e.g. imitate-walk-2d)"
        )
    if scene.action.targets:
        raise SpecError(
            f"{where}: scene {scene.name!r} acts by joint targets (action.kind joint_targets); "
            "a warm start from recorded excitations needs action.kind excitations"
        )
    if spec.excitations != imitate.motion:
        raise SpecError(
            f"{where}.excitations: {spec.excitations!r}: the excitations must be those of the "
            f"motion the scene imitates ({imitate.motion!r}), whose phase it observes"
        )
    try:
        excitation_table(scene.body, spec.excitations)
    except ExcitationError as exc:
        raise SpecError(f"{where}.excitations: {exc}") from None
