"""What the trainer does around its iterations besides PPO, as hooks: the blend ramp, the
iteration's metrics (history, TensorBoard, the progress callback) and the checkpoints.
Stage judging and recordings are hooks too (``learner.evaluation.training_hooks``: they run
evaluations and write MCAP, which the trainer's core leaves to them).

The trainer calls every hook, in its list's order, at each of the points of
:class:`TrainingHook`; an iteration's end runs judging, then metrics, then checkpoints, then
recordings, so that a checkpoint holds the evaluation of its network and a recording names
the checkpoint it shows.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from gaitforge.learner.checkpoint import save_checkpoint
from gaitforge.learner.job import CheckpointSpec
from gaitforge.learner.run_log import ScalarLog
from gaitforge.learner.run_state import RunState
from gaitforge.learner.transitions import collapsed, ramp_alpha

logger = logging.getLogger(__name__)

IterationCallback = Callable[[dict], None]
"""called with each iteration's metrics (a progress display)"""


class TrainingHook:
    """Something done around the trainer's iterations; each method does nothing unless a
    hook overrides it. ``run`` is the run's state, which a hook may change (a new network
    goes through ``run.switch_policy``)."""

    def after_update(self, run: RunState) -> None:
        """After PPO's update, before its weights are published: the workers get the policy
        as this leaves it."""

    def on_iteration_end(self, run: RunState, metrics: dict) -> None:
        """After the new weights are published. ``metrics`` are the iteration's (a hook may
        add to them); ``metrics["verdict"]`` says why the stage ends after this iteration
        (``learner.curriculum.CurriculumState.verdict``), None while it goes on."""

    def on_run_end(self, run: RunState) -> None:
        """When the trainer's loop has ended (the last stage, the iteration or time limit, or
        a stop), before ``Trainer.run`` returns; not after an error."""

    def close(self) -> None:
        """After the loop, also after an error: release files and writers."""


class BlendRamp(TrainingHook):
    """A blend's alpha goes 0 -> 1 over the stage's ``blend.ramp_env_steps`` from where its
    ramp started (``run.blend_start``); at 1 the blend collapses to pi_new (pi_old no longer
    acts) and the workers get that network."""

    def after_update(self, run: RunState) -> None:
        ramp = run.stage.blend.ramp_env_steps
        if ramp_alpha(run.policy, run.curriculum.stage_env_steps, run.blend_start, ramp):
            # the optimizer holds pi_new's parameters only: it goes on
            run.ppo.policy = collapsed(run.policy)
            run.rollouts.set_policy(run.policy)


class MetricsReport(TrainingHook):
    """Every iteration's metrics kept in :attr:`history`, written as TensorBoard scalars to
    ``log_dir`` (if ``tensorboard``) and passed to :attr:`callback` (if set)."""

    def __init__(
        self, log_dir: Path, tensorboard: bool, callback: IterationCallback | None
    ) -> None:
        self.history: list[dict] = []
        self.scalars = ScalarLog(log_dir, enabled=tensorboard)
        self.callback = callback

    def on_iteration_end(self, run: RunState, metrics: dict) -> None:
        self.history.append(metrics)
        self.scalars.log(metrics)
        if self.callback is not None:
            self.callback(metrics)

    def close(self) -> None:
        self.scalars.close()


def recording_due(spec: CheckpointSpec, iteration: int, verdict: str | None) -> bool:
    """Whether iteration ``iteration`` (1-based) is recorded: at a stage's end (``verdict``)
    and every ``spec.record_every_iters`` iterations (if set)."""
    every = spec.record_every_iters
    return verdict is not None or (every > 0 and iteration % every == 0)


class Checkpoints(TrainingHook):
    """A checkpoint of the run every ``checkpoint.every_iters`` iterations, at each stage's
    end and wherever a recording is due (:func:`recording_due`: a recording names the
    checkpoint it shows), in ``run.checkpoint_dir``; and of the last iteration when the loop
    ends, if it has none yet."""

    def __init__(self) -> None:
        self.written: Path | None = None
        """the checkpoint written at the iteration that just ended (None if none was)"""
        self._last_metrics: dict | None = None
        self._written_at = 0
        """the iteration of the last checkpoint written"""

    def on_iteration_end(self, run: RunState, metrics: dict) -> None:
        self._last_metrics = metrics
        spec = run.job.checkpoint
        due = run.iteration % spec.every_iters == 0
        if due or recording_due(spec, run.iteration, metrics["verdict"]):
            self.written = self.write(run, metrics)
        else:
            self.written = None

    def on_run_end(self, run: RunState) -> None:
        last = self._last_metrics
        if last is not None and last["iteration"] > self._written_at:
            self.write(run, last)

    def write(self, run: RunState, metrics: dict) -> Path:
        """A checkpoint of ``run`` now, ``metrics`` the last iteration's."""
        self._written_at = run.iteration
        return save_checkpoint(
            run.checkpoint_dir,
            run.env_steps,
            run.policy.state_dict(),
            run.meta(metrics),
            keep_last=run.job.checkpoint.keep_last,
            best_metric="return",
            optimizer_state=run.optimizer.state_dict(),
        )
