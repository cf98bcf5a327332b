"""Training operations: a job (file or spec) with overrides and budget scaling, a run that can
be stopped cleanly between iterations, and one-line status reports for logs.

    training = prepare_training(TrainRequest(job_file=Path("examples/stand-2d.yaml")))
    result = training.run(on_iteration=ProgressLog(every_s=10.0))
    # from another thread or a signal handler: training.request_stop()
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gaitforge.learner.job import LoadedJob, load_job, prepare_job, scaled_budgets
from gaitforge.learner.metrics import CONFIRMATION_KEY
from gaitforge.workers.overrides import set_fields
from gaitforge.workers.spec_types import Seed
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    from collections.abc import Callable

    from gaitforge.learner.trainer import Trainer

logger = logging.getLogger(__name__)


class TrainRequest(BaseModel):
    """What to train and how; exactly one of ``job_file`` and ``job``."""

    model_config = ConfigDict(extra="forbid")

    job_file: Path | None = Field(default=None, description="a job YAML file")
    job: dict[str, Any] | None = Field(
        default=None,
        description="a job spec (as in a job file); scene paths relative to ``base_dir``",
    )
    base_dir: Path = Field(default=Path("."), description="where ``job``'s scene paths start")
    run_dir: Path | None = Field(
        default=None,
        description="checkpoints, TensorBoard and recordings; resumes from its "
        "latest checkpoint (default: runs/<job name>)",
    )
    workers: int | None = Field(
        default=None, ge=0, description="Ray rollout actors (0: in-process); overrides the job"
    )
    address: str | None = Field(default=None, description="Ray cluster address to join")
    budget_scale: float = Field(
        default=1.0, gt=0, le=100, description="multiplies every stage's env-step budget"
    )
    seed: Seed | None = Field(default=None, description="the job's seed, in place of its own")
    overrides: dict[str, Any] = Field(
        default_factory=dict,
        description="job fields set by dotted path (``ppo.lr``, ``stages.1.env_steps``), "
        "before the job is checked",
    )
    tensorboard: bool = Field(default=True, description="write TensorBoard scalars")

    @model_validator(mode="after")
    def _one_job(self) -> TrainRequest:
        if (self.job_file is None) == (self.job is None):
            raise ValueError("give a job file or a job spec, not both or neither")
        return self


class TrainResult(BaseModel):
    """Where a run stands when :meth:`Training.run` returns."""

    run_dir: Path
    checkpoint: Path | None = Field(description="the newest checkpoint (None: none yet)")
    iterations: int = Field(description="PPO updates made by this call")
    iteration: int = Field(description="PPO updates of the run so far")
    env_steps: int = Field(description="env steps of the run so far")
    stage: int = Field(description="index of the current stage (= stages when finished)")
    finished: bool = Field(description="every stage is over")
    stopped: bool = Field(description="ended early by request_stop (a signal, a cancel)")


def load_request(request: TrainRequest) -> LoadedJob:
    """The request's job with its overrides (``seed``, ``workers``, ``address``, the dotted
    ``overrides``, then ``budget_scale``), validated once, and each stage's scenes resolved
    once.

    Raises:
        SpecError: a bad job file or spec, one line naming the file and the field.
    """
    overrides = dict(request.overrides)
    for field, value in (
        ("seed", request.seed),
        ("workers.num_workers", request.workers),
        ("workers.ray_address", request.address),
    ):
        if value is not None:
            overrides[field] = value
    if request.job_file is not None:
        return load_job(request.job_file, overrides, request.budget_scale)
    raw = set_fields(request.job or {}, overrides, where="overrides")
    return prepare_job(scaled_budgets(raw, request.budget_scale), request.base_dir, "job")


class Training:
    """A prepared run: the job, its scenes and the trainer (resumed from ``run_dir``)."""

    def __init__(self, loaded: LoadedJob, run_dir: Path, tensorboard: bool = True) -> None:
        from gaitforge.learner.trainer import Trainer  # lazy: imports torch

        self.job, self.scenes = loaded.job, loaded.scenes
        self.run_dir = run_dir
        self.trainer: Trainer = Trainer(
            loaded.job, run_dir, loaded.scenes, loaded.judged, tensorboard=tensorboard
        )
        self._started_ray = False
        self._stopped = False

    def stage_progress(self) -> list[int]:
        """Env steps done in each stage (a finished stage counts its whole budget)."""
        stages, current = self.job.stages, self.trainer.curriculum.stage
        done = [s.env_steps if i < current else 0 for i, s in enumerate(stages)]
        if not self.trainer.done:
            done[current] = self.trainer.curriculum.stage_env_steps
        return done

    @property
    def uses_ray(self) -> bool:
        return self.job.workers.num_workers != 0

    def start_ray(self) -> bool:
        """Start (or join, with ``workers.ray_address``) Ray now if the job's rollouts run on
        Ray actors and Ray is not up, so that a caller can install its signal handlers after
        Ray's; True if this call started it (:meth:`close` then shuts it down)."""
        if not self.uses_ray:
            return False
        import ray  # lazy: in-process training needs no Ray
        from gaitforge.workers.ray_start import start_ray

        if ray.is_initialized():
            return False
        start_ray(self.job.workers.ray_address)
        self._started_ray = True
        return True

    def request_stop(self) -> None:
        """Stop with a checkpoint of the last update (the batch being gathered is dropped); safe
        from a signal handler."""
        self._stopped = True
        self.trainer.request_stop()

    def run(
        self,
        max_iterations: int | None = None,
        max_seconds: float | None = None,
        on_iteration: Callable[[dict], None] | None = None,
    ) -> TrainResult:
        """Train until every stage is over, ``max_iterations`` more updates, ``max_seconds`` of
        wall-clock time (checked between updates) or :meth:`request_stop`; the last update is
        checkpointed; ``on_iteration`` sees each iteration's metrics."""
        trainer = self.trainer
        trainer.on_iteration = on_iteration
        start = trainer.iteration
        trainer.run(max_iterations=max_iterations, max_seconds=max_seconds)
        return TrainResult(
            run_dir=self.run_dir,
            checkpoint=newest_checkpoint(self.run_dir),
            iterations=trainer.iteration - start,
            iteration=trainer.iteration,
            env_steps=trainer.env_steps,
            stage=trainer.curriculum.stage,
            finished=trainer.done,
            stopped=self._stopped and not trainer.done,
        )

    def close(self) -> None:
        """Shut Ray down if :meth:`start_ray` started it."""
        if self._started_ray:
            import ray

            ray.shutdown()
            self._started_ray = False


def newest_checkpoint(run_dir: Path) -> Path | None:
    """The newest checkpoint of the run in ``run_dir`` (None: none yet)."""
    from gaitforge.learner.checkpoint import latest_checkpoint  # lazy: imports torch

    return latest_checkpoint(run_dir / "checkpoints")


def prepare_training(request: TrainRequest) -> Training:
    """Load and check the request's job and build its trainer (resuming from the run
    directory's newest checkpoint).

    Raises:
        SpecError: a bad job (file, field) or a stage check failing (one line).
    """
    loaded = load_request(request)
    run_dir = request.run_dir or Path("runs") / loaded.job.name
    return Training(loaded, run_dir, tensorboard=request.tensorboard)


def start_line(training: Training) -> str:
    """One line saying what a run is about to do."""
    job, trainer = training.job, training.trainer
    workers = job.workers.num_workers
    where = "in-process" if workers == 0 else f"on {workers or 'all CPUs but one as'} Ray actor(s)"
    resumed = f"; resumed at iteration {trainer.iteration}" if trainer.iteration else ""
    backends = dict.fromkeys(job.stage_backend(i) for i in range(len(job.stages)))
    return (
        f"training {job.name}: {len(job.stages)} stage(s) on {', '.join(backends)}, rollouts "
        f"{where}, run directory {training.run_dir}{resumed}"
    )


def status_line(m: dict) -> str:
    """One line of an iteration's metrics: stage, env steps, speed, return, falls, and the
    stage's deterministic evaluation where one ran (``learner.evaluation.stage_judge``; the
    pelvis's mean turn where it turned), with its confirmation on fresh episodes where it
    passed (promoted only if that passes too)."""
    verdict = f" ({m['verdict']})" if m.get("verdict") else ""
    evaluated = ""
    if "eval_fall_rate" in m:
        evaluated = (
            f"; evaluated: return {m['eval_return']:.1f}, speed {m['eval_speed']:.2f} m/s, "
            f"falls {100 * m['eval_fall_rate']:.0f} %"
        )
        if m.get("eval_turned"):
            evaluated += f", turned {m['eval_turned']:.0f} deg"
    confirmation = f"{CONFIRMATION_KEY}eval_fall_rate"
    if confirmation in m:
        evaluated += (
            f"; on fresh episodes: speed {m[f'{CONFIRMATION_KEY}eval_speed']:.2f} m/s, "
            f"falls {100 * m[confirmation]:.0f} %"
        )
    if "kept_best_from_env_steps" in m:
        evaluated += (
            f"; ends with the best, from {m['kept_best_from_env_steps']:,} env steps (falls "
            f"{100 * m['kept_eval_fall_rate']:.0f} %, speed {m['kept_eval_speed']:.2f} m/s)"
        )
    where = (
        f"stage {m['stage']} {m['stage_name']}{verdict}: iteration {m['iteration']}, "
        f"{m['env_steps']:,} env steps ({m['stage_env_steps']:,} in stage), "
        f"{m['steps_per_s']:,.0f} steps/s; "
    )
    if "cmaes_generation" in m:  # a CMA-ES stage's generation
        return where + (
            f"generation {m['cmaes_generation']}: best {m['cmaes_best']:.3f}, mean "
            f"{m['cmaes_mean']:.3f}, sigma {m['cmaes_sigma']:.3f}; the best alive "
            f"{100 * m['cmaes_best_alive']:.0f} % of its episodes, {m['cmaes_best_speed']:.2f} m/s"
        )
    return where + (
        f"return {m['return']:.1f}, speed {m['speed']:.2f} m/s, "
        f"falls {100 * m['fall_rate']:.0f} %{evaluated}"
    )


class ProgressLog:
    """An ``on_iteration`` callback that logs :func:`status_line` at INFO (logger
    ``gaitforge.service.ops.train``) at most once every ``every_s`` seconds, and at each
    stage's end and evaluation; the first iteration is logged at once."""

    def __init__(self, every_s: float = 10.0) -> None:
        self.every_s = every_s
        self._last: float | None = None

    def __call__(self, metrics: dict) -> None:
        now = time.monotonic()
        due = self._last is None or now - self._last >= self.every_s
        if due or metrics.get("verdict") or "eval_fall_rate" in metrics:
            self._last = now
            logger.info("%s", status_line(metrics))
