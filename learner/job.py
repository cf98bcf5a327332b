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
from typing import Annotated, Any, Literal

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
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import (
    SpecError,
    format_validation_error,
    read_yaml_mapping,
    validate_model,
)
from gaitforge.workers.spec_types import Name, Ref, Seed
from pydantic import Field, ValidationError, model_validator

__all__ = [
    "MAX_NUM_WORKERS",
    "MAX_STAGES",
    "METRICS",
    "BlendSpec",
    "CheckpointSpec",
    "Job",
    "NetworkSpec",
    "PromotionRule",
    "Stage",
    "StageEvaluation",
    "StagePPO",
    "WorkersSpec",
    "evaluation_scene",
    "job_changes",
    "load_job",
    "resolve_scenes",
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
    (``transition: blend`` with its own ``network``), as a later
    stage grows one from the stage before"""
    init_from_action_std: Annotated[float, Field(gt=0, le=1)] | None = None
    """with ``init_from``: the action noise's standard deviation (action units) the loaded
    network starts with, in place of the one it was trained down to (a fine-tune that must
    learn something new explores again); None keeps the checkpoint's"""
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
        if first.action_std is not None:
            raise ValueError(
                "stages.0.action_std: the first stage starts at network.init_std, or with "
                "init_from at init_from_action_std"
            )
        if self.init_from_action_std is not None and self.init_from is None:
            raise ValueError("init_from_action_std: only with init_from (a network to reset)")
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


def load_job(path: Path, overrides: dict[str, Any] | None = None) -> tuple[Job, list[Scene]]:
    """Read and check a job file (:func:`read_job_fields`: its ``extends`` followed, then
    ``overrides`` set by dotted path); returns the job and each stage's resolved scene (with
    the stage's scene overrides applied).

    Raises:
        SpecError: one line naming the file, the field and what is allowed.
    """
    job = validate_model(read_job_fields(path, overrides), Job, str(path))
    if job.init_from is not None:
        start = (path.parent / job.init_from).resolve()
        if not (start / "meta.json").is_file():
            raise SpecError(
                f"{path}: init_from: {job.init_from!r}: no checkpoint there (a directory with "
                "meta.json and policy.safetensors, as the trainer writes them)"
            )
        job = job.model_copy(update={"init_from": str(start)})
    job = with_evaluation_paths(job, path.parent)
    return job, resolve_scenes(job, base=path.parent, source=str(path))


def read_job_fields(
    path: Path, overrides: dict[str, Any] | None = None, seen: tuple[Path, ...] = ()
) -> dict[str, Any]:
    """The fields of job file ``path`` before validation, with ``overrides`` (dotted path ->
    value) set last.

    A recipe that is part of another reuses it by reference: ``extends: other.yaml`` takes
    that job's fields (its paths made relative to this file), and this file's fields go over
    them (mappings merged: ``ppo: {lr: 1e-4}`` keeps the other PPO settings); ``stages``
    given as a list of names picks those stages of the other job, in order (its stages are
    named by ``name``, else their scene). A picked first stage's ``action_std`` becomes
    ``init_from_action_std`` (the noise the loaded network starts with). ``set: {dotted
    path: value}`` then sets single fields (``stages.0.action: {kind: joint_targets}``).

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
            first_std = base["stages"][0].pop("action_std", None)
            if first_std is not None:
                base["init_from_action_std"] = first_std
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


def resolve_scenes(job: Job, base: Path = Path("."), source: str = "job") -> list[Scene]:
    """Each stage's scene, checked against the job's backend and resolved on this machine
    (``Scene.resolved``: named, saved and ``auto`` fidelity profiles become concrete ones),
    so that actors on any node and the checkpoints get the profile chosen here."""
    scenes = []
    for i, stage in enumerate(job.stages):
        ref = _scene_ref(stage.scene, base)
        try:
            scene = load_scene(ref, stage.scene_set)
        except SpecError as exc:
            field = "scene_set" if stage.scene_set and _loads(ref) else "scene"
            raise SpecError(f"{source}: stages.{i}.{field}: {exc}") from None
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
        if stage.evaluate is not None and stage.evaluate.scene is not None:
            where = f"{source}: stages.{i}.evaluate.scene"
            ref = _scene_ref(stage.evaluate.scene, base)
            evaluation_scene(ref, backend, where, stage.scene_set)
    return scenes


def _loads(ref: str) -> bool:
    """Whether scene ``ref`` loads as it is (so a failure with overrides is theirs)."""
    try:
        load_scene(ref)
    except SpecError:
        return False
    return True


def evaluation_scene(
    ref: str, backend: str, where: str, scene_set: dict[str, Any] | None = None
) -> Scene:
    """A stage's evaluation scene (``evaluate.scene`` with the stage's ``scene_set``), loaded
    and resolved for ``backend`` (that it takes the stage's policy is checked with the
    stage's names: ``learner.evaluation.stage_judge.judged_scene``).

    Raises:
        SpecError: ``where`` (file and field): the scene does not load or runs elsewhere.
    """
    try:
        scene = load_scene(ref, scene_set)
    except SpecError as exc:
        raise SpecError(f"{where}: {exc}") from None
    if backend not in scene.backends:
        raise SpecError(f"{where}: {scene.name!r} runs on {scene.backends}, not on {backend!r}")
    try:
        return scene.resolved()
    except ValueError as exc:
        raise SpecError(f"{where}: {exc}") from None
