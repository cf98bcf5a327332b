"""What a checkpoint's ``meta.json`` holds: :class:`CheckpointMeta`, read in one place
(:func:`read_meta`) and written by ``learner.checkpoint.save_checkpoint``.

``schema_version`` says which layout a file has; :func:`read_meta` migrates older versions
on read (:func:`migrate`), so callers only ever see the current model; a file from a newer
gaitforge fails loudly rather than being half understood.

- Version 0 is the layout before it had one (gaitforge up to commit 22a0f9c): the same keys
  as version 1, no ``schema_version``.
- Version 1: its stored scene may be in an older scene layout and its job sets scene
  fields on a stage, ``init_from_action_std`` and retired fields (up to commit cfcf6fc).
- Version 2 (current): the scene in today's layout, the job as today's job files write it;
  older versions become it by ``workers.scenes.migration`` (``read_older_layout`` on the
  scene, ``read_older_job`` on the job).

The trainer fills every field; checkpoints written by hand (tests, scripts) may leave out
what they have no use for (a policy to evaluate needs ``network`` and ``scene``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.migration import read_older_job, read_older_layout
from pydantic import BaseModel, ConfigDict, Field, ValidationError

SCHEMA_VERSION = 2
META_FILE = "meta.json"

MetricValue = bool | int | float | str | None
"""One number (or label) of an iteration's metrics: JSON scalars only."""


class CheckpointError(RuntimeError):
    """A checkpoint is missing, damaged or inconsistent; the message names the file."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RunConfig(_Model):
    """How the run was simulated."""

    backend: Literal["mujoco", "opensim"] = "mujoco"
    """the simulator the policy was trained on"""


class StageMeta(_Model):
    """The curriculum stage the checkpoint was written in."""

    index: int = Field(ge=0)
    """position in the job's ``stages`` (0-based)"""
    name: str
    """the stage's name (its scene's name unless the job names it)"""
    env_steps: int = Field(ge=0)
    """env steps (control steps, all envs) spent in this stage so far"""


class CurriculumMeta(_Model):
    """``learner.curriculum.CurriculumState.to_json()``: where the run is in its stages and
    the recent episodes behind its promotion rules (so a resumed run keeps its window)."""

    stage: int = Field(ge=0)
    """index of the current stage"""
    stage_env_steps: int = Field(ge=0)
    """env steps spent in it"""
    entered: bool
    """the stage's transition (scene push, new network) is done"""
    episodes: list[tuple[float, float, float, bool, bool]] = Field(default_factory=list)
    """the last (up to 1000) finished episodes, oldest first: return, distance (m),
    length (s), fell, lasted the whole episode"""


class LineageEntry(_Model):
    """One network the run has trained: where it started and how it was built."""

    stage: int = Field(ge=0)
    """the stage that built it"""
    transition: Literal["initial", "init_from", "continue", "blend", "distil", "scratch"]
    """how: ``initial`` for a fresh first network, ``init_from`` for one loaded from the
    job's ``init_from`` checkpoint, else the stage's transition (``distil`` and ``scratch``
    only in the lineage of checkpoints from before those transitions were retired)"""
    network: dict[str, Any]
    """its description (``policy.describe()``)"""
    env_steps: int = Field(ge=0)
    """the run's env steps when it was built"""
    source: str | None = None
    """``init_from``: the checkpoint it was loaded from"""


class CheckpointMeta(_Model):
    """The contents of a checkpoint's ``meta.json`` (current schema)."""

    schema_version: int = SCHEMA_VERSION
    """layout version; files without one are version 0 and are migrated on read"""
    env_steps: int = Field(0, ge=0)
    """the run's env steps (control steps summed over all envs) when it was written;
    also the checkpoint directory's name (``ckpt-<env_steps, 12 digits>``)"""
    versions: dict[str, str] = Field(default_factory=dict)
    """package name -> installed version when it was written ("not installed" if absent)"""
    network: dict[str, Any] | None = None
    """the policy's description (``policy.describe()``) for ``learner.policy.build_policy``"""
    obs_names: list[str] | None = None
    """the policy's observation names, in input order"""
    scene: dict[str, Any] | None = None
    """the stage's resolved scene (``Scene.model_dump(mode="json")``); see :meth:`scene_spec`"""
    config: RunConfig = Field(default_factory=RunConfig)
    job: dict[str, Any] | None = None
    """the validated job (``Job.model_dump(mode="json")``)"""
    iteration: int | None = Field(None, ge=0)
    """PPO updates done so far"""
    stage: StageMeta | None = None
    curriculum: CurriculumMeta | None = None
    blend_start: int = Field(0, ge=0)
    """stage env steps at which the current stage's blend ramp started"""
    lineage: list[LineageEntry] = Field(default_factory=list)
    """every network of the run, oldest first"""
    metrics: dict[str, MetricValue] = Field(default_factory=dict)
    """the last iteration's metrics (``Trainer.history`` entries without the nested
    dicts): ``return``, ``distance`` (m), ``speed`` (m/s), ``fall_rate``, ``survival`` (over the
    last 100 episodes), losses, ``lr``, ``steps_per_s``, and ``verdict`` (why the stage ended,
    set only in the checkpoint written at a stage's end)"""
    optimizer_param_groups: list[dict[str, Any]] | None = None
    """the optimizer's param groups when ``optimizer.safetensors`` holds its state"""
    provenance: dict[str, Any] | None = None
    """a shipped policy (``learner.evaluation.ship``): the command, seed and commit that made
    it, the checkpoint it was copied from and, if given, its evaluation's headline figures"""

    @property
    def backend(self) -> str:
        return self.config.backend

    def metric(self, name: str) -> float | None:
        """``metrics[name]`` if it is a finite number, else None."""
        value = self.metrics.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float):
            return None
        return float(value) if math.isfinite(value) else None

    def check_resumable(self, source: Path | str) -> None:
        """Raise ``CheckpointError`` (naming ``source``) unless the trainer can resume from
        this: it holds the network, observation names, iteration and curriculum."""
        missing = [
            k
            for k in ("network", "obs_names", "iteration", "curriculum")
            if getattr(self, k) is None
        ]
        if missing:
            raise CheckpointError(f"{source}: no {missing} (not written by the trainer)")

    def scene_spec(self, source: Path | str = META_FILE) -> Scene:
        """The stored scene as a validated ``Scene``.

        Raises:
            CheckpointError: no scene stored, or it does not validate (names ``source``).
        """
        if self.scene is None:
            raise CheckpointError(f"{source}: no 'scene'; give a scene to evaluate on")
        try:
            return Scene.model_validate(self.scene)
        except ValidationError as exc:
            first = str(exc).splitlines()[0]
            raise CheckpointError(f"{source}: scene does not validate ({first})") from None

    def to_json(self) -> str:
        return json.dumps(self.model_dump(mode="json"), indent=2, sort_keys=True, default=str)


def migrate(raw: dict[str, Any], source: Path) -> dict[str, Any]:
    """``raw`` (a ``meta.json``'s object of any known schema version) in the current layout;
    ``raw`` itself is left as it is.

    Raises:
        CheckpointError: a version that is not one, or newer than this gaitforge reads.
    """
    version = raw.get("schema_version", 0)
    if not isinstance(version, int) or isinstance(version, bool) or version < 0:
        raise CheckpointError(f"{source}: schema_version {version!r} is not a version")
    if version > SCHEMA_VERSION:
        raise CheckpointError(
            f"{source}: schema_version {version} is newer than this gaitforge reads "
            f"({SCHEMA_VERSION}); upgrade gaitforge"
        )
    if version < SCHEMA_VERSION:
        raw = dict(raw)
        if isinstance(raw.get("scene"), dict):
            try:
                raw["scene"] = read_older_layout(raw["scene"])
            except ValueError as exc:
                raise CheckpointError(f"{source}: scene: {exc}") from None
        if isinstance(raw.get("job"), dict):
            raw["job"] = read_older_job(raw["job"])
        raw["schema_version"] = SCHEMA_VERSION
    return raw


def parse_meta(raw: dict[str, Any], source: Path | str = META_FILE) -> CheckpointMeta:
    """``raw`` (a ``meta.json``'s object, any known version) as the current model.

    Raises:
        CheckpointError: a newer or unknown version, or a field that does not validate.
    """
    source = Path(source)
    if not isinstance(raw, dict):
        raise CheckpointError(f"{source}: expected a JSON object")
    try:
        return CheckpointMeta.model_validate(migrate(raw, source))
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(part) for part in error["loc"]) or "<root>"
        raise CheckpointError(f"{source}: {where}: {error['msg']}") from None


def read_meta(ckpt_dir: Path) -> CheckpointMeta:
    """The metadata of checkpoint directory ``ckpt_dir`` (migrated to the current schema).
    Reads ``meta.json`` only; ``learner.checkpoint.load_checkpoint`` also checks hashes.

    Raises:
        CheckpointError: missing, not JSON, or not valid metadata (naming the file).
    """
    path = Path(ckpt_dir) / META_FILE
    try:
        raw = json.loads(path.read_text())
    except FileNotFoundError:
        raise CheckpointError(f"{path}: missing") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: unreadable ({exc})") from None
    return parse_meta(raw, path)
