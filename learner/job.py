"""The job file: a body's curriculum of stages, PPO settings, workers and checkpoints.

Validated once, early (``load_job``): every scene must load, each stage's scene must run on
the job's backend, and a network change between stages needs a transition that builds a new
network (``blend``). Errors are one line naming the file and field.

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
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

from gaitforge.learner.ppo import PPOSettings
from gaitforge.learner.stage_spec import (
    METRICS,
    BlendSpec,
    NetworkSpec,
    PromotionRule,
    Stage,
    StageEvaluation,
    StagePPO,
    StrictSpec,
)
from gaitforge.workers.overrides import set_fields
from gaitforge.workers.scenes import BackendMismatch, Scene, load_scene
from gaitforge.workers.spec_io import (
    SpecError,
    read_yaml_mapping,
    validate_model,
)
from gaitforge.workers.spec_types import Name, Ref, Seed
from pydantic import Field, model_validator

__all__ = [
    "MAX_NUM_WORKERS",
    "MAX_STAGES",
    "METRICS",
    "BlendSpec",
    "CheckpointSpec",
    "Job",
    "LoadedJob",
    "NetworkSpec",
    "PromotionRule",
    "Stage",
    "StageEvaluation",
    "StagePPO",
    "WorkersSpec",
    "evaluation_scene",
    "job_changes",
    "load_job",
    "prepare_job",
    "resolve_scenes",
    "scaled_budgets",
    "with_evaluation_paths",
]


MAX_NUM_WORKERS = 1024
"""the most rollout actors a job may ask for (each takes one CPU of the cluster)"""
MAX_STAGES = 64
"""the most stages a job may have"""


class WorkersSpec(StrictSpec):
    num_workers: Annotated[int, Field(ge=0, le=MAX_NUM_WORKERS)] | None = None
    """Ray rollout actors, one CPU each (None: the cluster's CPUs less one; 0: one
    in-process worker); at most the cluster's CPUs where it cannot grow"""
    envs_per_worker: Annotated[int, Field(ge=1, le=1024)] = 8
    fragment_length: Annotated[int, Field(ge=8, le=100_000)] = 128
    ray_address: Ref | None = None
    """a Ray cluster to join ("auto", "ray://host:10001"); None: start a local one"""
    timeout_s: Annotated[float, Field(gt=0)] = 600.0
    """an actor with no fragment for this long is replaced"""
    max_actor_failures: Annotated[int, Field(ge=1, le=100_000)] | None = None
    """actor failures (deaths, timeouts) the pool replaces within ``actor_failure_window_s``;
    one more fails the job with the actors' own error (an actor that cannot start, e.g. a
    simulator that fails on creation, would otherwise be replaced forever). None: twice the
    actors, at least 10 (``workers.pool.default_max_failures``)"""
    actor_failure_window_s: Annotated[float, Field(gt=0, le=86_400)] = 300.0
    """the window (s) in which ``max_actor_failures`` are counted"""


class CheckpointSpec(StrictSpec):
    every_iters: Annotated[int, Field(ge=1)] = 10
    keep_last: Annotated[int, Field(ge=1)] = 3
    record_every_iters: Annotated[int, Field(ge=0)] = 0
    """an MCAP recording of one deterministic episode every N iterations (0: at stage ends
    only)"""


class LoadedJob(NamedTuple):
    """A job validated once, with each stage's scenes resolved once."""

    job: Job
    scenes: list[Scene]
    """each stage's scene, as it trains"""
    judged: dict[int, Scene]
    """stage index -> the scene it is judged on, for the stages with ``evaluate.scene``"""


class Job(StrictSpec):
    """A training job: the first network, PPO, workers, checkpoints and the stages."""

    name: Name
    """letters, digits and ``_.-`` (a letter or digit first), at most 128 characters: the
    default run directory is ``runs/<name>``"""
    backend: Literal["mujoco", "opensim"] = "mujoco"
    seed: Seed = 0
    """an integer in [0, 2**32): the learner's torch seed, and the actors' seeds from it"""
    network: NetworkSpec = NetworkSpec()
    ppo: PPOSettings = PPOSettings()
    """PPO settings and schedules (``learner.ppo.PPOSettings``)"""
    workers: WorkersSpec = WorkersSpec()
    checkpoint: CheckpointSpec = CheckpointSpec()
    init_from: Ref | None = None
    """a checkpoint directory (relative to the job file) whose network and observation
    statistics start the first stage, for fine-tuning a trained policy on another scene or
    backend (the optimizer, curriculum and env-step count start afresh); e.g.
    ``examples/policies/walk-2d``. The first stage may then grow a new network from it
    (``transition: blend`` with its own ``network``), as a later stage grows one from the
    stage before; the first stage's ``action_std`` starts the loaded network's action noise
    anew"""
    stages: list[Stage] = Field(min_length=1, max_length=MAX_STAGES)

    def stage_backend(self, index: int) -> str:
        """The simulator of stage ``index``: its own ``backend``, else the job's."""
        return self.stages[index].backend or self.backend

    def stage_ppo(self, index: int) -> PPOSettings:
        """The PPO settings of stage ``index``: the job's, with the stage's own schedules and
        batch."""
        return self.ppo.model_copy(update=self.stages[index].ppo.model_dump(exclude_none=True))

    @model_validator(mode="after")
    def _first_stage(self) -> Job:
        first = self.stages[0]
        if (first.transition != "continue" or first.network is not None) and not self.init_from:
            raise ValueError(
                "stages.0: the first stage uses the job's network (no transition); a transition "
                "(blend) there needs init_from, the network it starts from"
            )
        if first.action_std is not None and self.init_from is None:
            raise ValueError(
                "stages.0.action_std: the first stage starts at network.init_std; only a "
                "network loaded with init_from has its noise started anew"
            )
        return self


def job_changes(saved: Any, given: Any, path: str = "") -> list[str]:
    """Where job dump ``given`` differs from ``saved`` (both ``Job.model_dump(mode="json")``,
    e.g. a checkpoint's job and the one a resume was given): one ``path: saved -> given``
    per differing value, with dict keys and list positions in the dotted path. A list of
    mappings (``stages``, ``promote``) that grew or shrank is said as its count of entries,
    the changes in the positions both have, then each entry only one has (by its name where
    it has one)."""
    if isinstance(saved, dict) and isinstance(given, dict):
        return [
            change
            for key in sorted(saved.keys() | given.keys())
            for change in job_changes(saved.get(key), given.get(key), f"{path}{key}.")
        ]
    if isinstance(saved, list) and isinstance(given, list):
        mappings = any(isinstance(entry, dict) for entry in saved + given)
        if len(saved) == len(given) or mappings:
            changes = [
                change
                for index, (before, after) in enumerate(zip(saved, given, strict=False))
                for change in job_changes(before, after, f"{path}{index}.")
            ]
            if len(saved) == len(given):
                return changes
            count = f"{path.rstrip('.')}: {len(saved)} entries -> {len(given)}"
            longer, word = (saved, "removed") if len(saved) > len(given) else (given, "added")
            only = [
                f"{path}{index}: {word} {_entry_label(longer[index])}"
                for index in range(min(len(saved), len(given)), len(longer))
            ]
            return [count, *changes, *only]
    return [] if saved == given else [f"{path.rstrip('.')}: {saved!r} -> {given!r}"]


def _entry_label(entry: Any) -> str:
    """A list entry as a change names it: a mapping with a name by its name, else whole."""
    if isinstance(entry, dict) and entry.get("name"):
        return repr(entry["name"])
    return repr(entry)


def load_job(
    path: Path, overrides: dict[str, Any] | None = None, budget_scale: float = 1.0
) -> LoadedJob:
    """Read and check a job file (:func:`read_job_fields`: its ``extends`` followed, then
    ``overrides`` set by dotted path, then every budget times ``budget_scale``), validated
    once; returns the job and each stage's scenes, resolved once (:func:`resolve_scenes`).

    Raises:
        SpecError: one line naming the file, the field and what is allowed.
    """
    raw = scaled_budgets(read_job_fields(path, overrides), budget_scale)
    return prepare_job(raw, path.parent, str(path))


def prepare_job(raw: dict[str, Any], base: Path, source: str) -> LoadedJob:
    """Job fields ``raw`` (relative paths from ``base``) validated once, ``init_from`` and the
    evaluation scenes' paths made absolute, each stage's scenes resolved once.

    Raises:
        SpecError: one line naming ``source``, the field and what is allowed.
    """
    job = validate_model(raw, Job, source)
    if job.init_from is not None:
        start = (base / job.init_from).resolve()
        if not (start / "meta.json").is_file():
            raise SpecError(
                f"{source}: init_from: {job.init_from!r}: no checkpoint there (a directory "
                "with meta.json and policy.safetensors, as the trainer writes them)"
            )
        job = job.model_copy(update={"init_from": str(start)})
    job = with_evaluation_paths(job, base)
    scenes, judged = resolve_scenes(job, base=base, source=source)
    return LoadedJob(job, scenes, judged)


def scaled_budgets(raw: dict[str, Any], scale: float) -> dict[str, Any]:
    """Job fields ``raw`` with every stage's env-step budget and blend ramp (its default
    where the stage gives none) times ``scale`` (at least 1), before validation: a smoke run
    at a fraction of a recipe's budget. Fields that are not numbers are left for validation
    to name."""
    if scale == 1.0:
        return raw
    stages = []
    for stage in raw.get("stages") or []:
        if isinstance(stage, dict):
            stage = dict(stage)
            if isinstance(stage.get("env_steps"), int):
                stage["env_steps"] = max(1, round(stage["env_steps"] * scale))
            blend = stage.get("blend")
            blend = dict(blend) if isinstance(blend, dict) else {}
            ramp = blend.get("ramp_env_steps", BlendSpec().ramp_env_steps)
            if isinstance(ramp, int):
                blend["ramp_env_steps"] = max(1, round(ramp * scale))
                stage["blend"] = blend
        stages.append(stage)
    return {**raw, "stages": stages} if "stages" in raw else raw


def read_job_fields(
    path: Path, overrides: dict[str, Any] | None = None, seen: tuple[Path, ...] = ()
) -> dict[str, Any]:
    """The fields of job file ``path`` before validation, with ``overrides`` (dotted path ->
    value) set last.

    A recipe that is part of another reuses it by reference: ``extends: other.yaml`` takes
    that job's fields (its paths made relative to this file), and this file's fields go over
    them (mappings merged: ``ppo: {lr: 1e-4}`` keeps the other PPO settings); ``stages``
    given as a list of names picks those stages of the other job, in order (its stages are
    named by ``name``, else their scene), each as it is written there. ``set: {dotted path:
    value}`` then sets single fields (``stages.0.scene_set: {action: {kind:
    joint_targets}}``).

    Raises:
        SpecError: the file or the one it extends does not read, a cycle of ``extends``, an
            unknown stage name, a bad override path.
    """
    raw = read_yaml_mapping(path)
    file_set = raw.pop("set", None) or {}
    if not isinstance(file_set, dict):
        raise SpecError(f"{path}: set: a mapping of dotted field paths to values")
    if "extends" in raw:
        base_ref = raw.pop("extends")
        if not isinstance(base_ref, str) or not base_ref.endswith((".yaml", ".yml")):
            raise SpecError(f"{path}: extends: a job file's path (.yaml), relative to this file")
        base_path = (path.parent / base_ref).resolve()
        if base_path in (*seen, path.resolve()):
            raise SpecError(f"{path}: extends: {base_ref!r} makes a cycle")
        base_fields = read_job_fields(base_path, seen=(*seen, path.resolve()))
        base = _relative_to(base_fields, base_path.parent, path.parent)
        picked = raw.pop("stages", None)
        if isinstance(picked, list) and picked and all(isinstance(n, str) for n in picked):
            base["stages"] = _pick_stages(base.get("stages") or [], picked, path)
        elif picked is not None:
            base["stages"] = picked
        raw = set_fields(base, raw, where=str(path))
    raw = set_fields(raw, file_set, where=f"{path}: set")
    if overrides:
        raw = set_fields(raw, overrides, where=f"{path}: --set")
    return raw


def _pick_stages(stages: list[Any], names: list[str], path: Path) -> list[Any]:
    """Copies of the stages called ``names`` (``name``, else the scene), in that order."""
    by_name = {
        stage.get("name") or stage.get("scene"): stage
        for stage in stages
        if isinstance(stage, dict)
    }
    missing = [name for name in names if name not in by_name]
    if missing:
        raise SpecError(f"{path}: stages: {missing} not in the job it extends: {list(by_name)}")
    return [dict(by_name[name]) for name in names]


def _relative_to(raw: dict[str, Any], source_dir: Path, target_dir: Path) -> dict[str, Any]:
    """A job's fields read in ``source_dir`` with their relative paths (``init_from``, scene
    files, evaluation scene files) rewritten to be read from ``target_dir``."""

    def moved(ref: Any, always: bool) -> Any:
        if not isinstance(ref, str) or Path(ref).is_absolute():
            return ref
        if not always and not ref.endswith((".yaml", ".yml")):
            return ref  # a catalogue scene
        return os.path.relpath(source_dir / ref, target_dir)

    out = dict(raw)
    if "init_from" in out:
        out["init_from"] = moved(out["init_from"], always=True)
    stages = []
    for stage in out.get("stages") or []:
        if isinstance(stage, dict):
            stage = dict(stage)
            stage["scene"] = moved(stage.get("scene"), always=False)
            if isinstance(stage.get("evaluate"), dict):
                evaluate = dict(stage["evaluate"])
                evaluate["scene"] = moved(evaluate.get("scene"), always=False)
                stage["evaluate"] = evaluate
        stages.append(stage)
    if "stages" in out:
        out["stages"] = stages
    return out


def _scene_ref(ref: str, base: Path) -> str:
    """A scene reference as loadable from here: a relative YAML path taken from ``base``
    (the job file's directory); a catalogue name or an absolute path as it is."""
    if ref.endswith((".yaml", ".yml")) and not Path(ref).is_absolute():
        return str(base / ref)
    return ref


def with_evaluation_paths(job: Job, base: Path) -> Job:
    """``job`` with each stage's ``evaluate.scene`` YAML path made absolute (relative to
    ``base``, the job file's directory), so the trainer finds it from any working directory."""
    stages = []
    for stage in job.stages:
        if stage.evaluate is not None and stage.evaluate.scene is not None:
            ref = _scene_ref(stage.evaluate.scene, base.resolve())
            stage = stage.model_copy(
                update={"evaluate": stage.evaluate.model_copy(update={"scene": ref})}
            )
        stages.append(stage)
    return job.model_copy(update={"stages": stages})


def resolve_scenes(
    job: Job, base: Path = Path("."), source: str = "job"
) -> tuple[list[Scene], dict[int, Scene]]:
    """Each stage's scene and, for a stage with ``evaluate.scene``, the scene it is judged
    on, loaded with the stage's ``scene_set`` (the one way a stage changes its scene),
    checked against the stage's backend and resolved on this machine (``Scene.resolved``:
    named, saved and ``auto`` fidelity profiles become concrete ones), so that actors on any
    node and the checkpoints get the profile chosen here. A stage that sets scene fields or
    its own backend has its scenes checked on that backend only. Returns the stages' scenes
    and stage index -> evaluation scene.

    Raises:
        SpecError: naming ``source`` and the stage's field.
    """
    scenes: list[Scene] = []
    judged: dict[int, Scene] = {}
    for i, stage in enumerate(job.stages):
        backend = job.stage_backend(i)
        where = f"{source}: stages.{i}"
        whose = f"stages.{i}.backend" if stage.backend else "the job's backend"
        scenes.append(_stage_scene(_scene_ref(stage.scene, base), stage, backend, where, whose))
        if stage.evaluate is not None and stage.evaluate.scene is not None:
            ref = _scene_ref(stage.evaluate.scene, base)
            judged[i] = evaluation_scene(ref, backend, f"{where}.evaluate.scene", stage)
    return scenes, judged


def _stage_scene(ref: str, stage: Stage, backend: str, where: str, whose: str) -> Scene:
    """Scene ``ref`` as stage ``stage`` sets it, resolved (:func:`_set_by_stage`).

    Raises:
        SpecError: ``where`` and the stage's ``scene`` or ``scene_set`` field, ``whose``
            backend named where the scene does not run on it.
    """
    try:
        return _set_by_stage(ref, stage, backend)
    except BackendMismatch as exc:
        raise SpecError(
            f"{where}.scene: {_name(ref)!r} runs on {exc.backends}, not on {whose} {backend!r}"
        ) from None
    except SpecError as exc:
        field = "scene_set" if stage.scene_set and _loads(ref) else "scene"
        problem = str(exc).replace(": <root>:", ":")  # a check of the whole scene
        raise SpecError(f"{where}.{field}: {problem}") from None


def _set_by_stage(ref: str, stage: Stage, backend: str) -> Scene:
    """Scene ``ref`` with the stage's ``scene_set``, on ``backend`` alone where the stage sets
    scene fields or a backend of its own, resolved.

    Raises:
        BackendMismatch: the scene does not run on ``backend``.
        SpecError: it does not load or resolve (one line naming the scene).
    """
    only = backend if stage.scene_set or stage.backend else None
    scene = load_scene(ref, stage.scene_set, only)
    if backend not in scene.backends:
        raise BackendMismatch(f"{ref}: runs on {scene.backends}", scene.backends)
    try:
        return scene.resolved()
    except ValueError as exc:
        raise SpecError(f"scene {scene.name!r}: {exc}") from None


def _name(ref: str) -> str:
    """A scene reference as an error names it: a catalogue name, or a file's stem."""
    return Path(ref).stem if ref.endswith((".yaml", ".yml")) else ref


def _loads(ref: str) -> bool:
    """Whether scene ``ref`` loads as it is (so a failure with overrides is theirs)."""
    try:
        load_scene(ref)
    except SpecError:
        return False
    return True


def evaluation_scene(ref: str, backend: str, where: str, stage: Stage) -> Scene:
    """A stage's evaluation scene (``evaluate.scene`` set as the stage sets its own scene),
    loaded and resolved for ``backend`` (that it takes the stage's policy is checked with
    the stage's names: ``learner.evaluation.stage_judge.judged_scene``).

    Raises:
        SpecError: ``where`` (file and field): the scene does not load or runs elsewhere.
    """
    try:
        return _set_by_stage(ref, stage, backend)
    except BackendMismatch as exc:
        message = f"{where}: {_name(ref)!r} runs on {exc.backends}, not on {backend!r}"
        raise SpecError(message) from None
    except SpecError as exc:
        raise SpecError(f"{where}: {exc}") from None
