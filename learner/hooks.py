"""What the trainer does around its iterations besides PPO: the blend ramp, the iteration's
metrics (history, TensorBoard, the progress callback) and the checkpoints. The stage's
verdict and the recordings are in ``learner.evaluation.training_hooks`` (they run
evaluations and write MCAP, which the trainer's core leaves to them).

``learner.trainer.Trainer.iterate`` calls them in the order their data needs: the verdict
(with the evaluation), then the metrics' report, then the checkpoint (it holds the
evaluation of its network), then the recording (it names the checkpoint it shows).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from gaitforge.learner.checkpoint import save_checkpoint
from gaitforge.learner.job import CheckpointSpec
from gaitforge.learner.run_log import ScalarLog
from gaitforge.learner.run_state import RunState
from gaitforge.learner.stage_verdict import StageVerdict
from gaitforge.learner.transitions import collapsed, ramp_alpha

logger = logging.getLogger(__name__)

IterationCallback = Callable[[dict], None]
"""called with each iteration's metrics (a progress display)"""


def ramp_blend(run: RunState) -> None:
    """After PPO's update, before its weights are published: a blend's alpha goes 0 -> 1 over
    the stage's ``blend.ramp_env_steps`` from where its ramp started (``run.blend_start``);
    at 1 the blend collapses to pi_new (pi_old no longer acts) and the workers get that
    network."""
    ramp = run.stage.blend.ramp_env_steps
    if ramp_alpha(run.policy, run.curriculum.stage_env_steps, run.blend_start, ramp):
        # the optimizer holds pi_new's parameters only: it goes on
        run.ppo.policy = collapsed(run.policy)
        run.rollouts.set_policy(run.policy)


class MetricsReport:
    """Every iteration's metrics kept in :attr:`history`, written as TensorBoard scalars to
    ``log_dir`` (if ``tensorboard``) and passed to :attr:`callback` (if set)."""

    def __init__(
        self, log_dir: Path, tensorboard: bool, callback: IterationCallback | None
    ) -> None:
        self.history: list[dict] = []
        self.scalars = ScalarLog(log_dir, enabled=tensorboard)
        self.callback = callback

    def add(self, metrics: dict) -> None:
        self.history.append(metrics)
        self.scalars.log(metrics)
        if self.callback is not None:
            self.callback(metrics)

    def close(self) -> None:
        self.scalars.close()


def recording_due(spec: CheckpointSpec, iteration: int, verdict: StageVerdict) -> bool:
    """Whether iteration ``iteration`` (1-based) is recorded: at a stage's end (``verdict``)
    and every ``spec.record_every_iters`` iterations (if set)."""
    every = spec.record_every_iters
    return verdict.ends or (every > 0 and iteration % every == 0)


class Checkpoints:
    """A checkpoint of the run every ``checkpoint.every_iters`` iterations, at each stage's
    end and wherever a recording is due (:func:`recording_due`: a recording names the
    checkpoint it shows), in ``run.checkpoint_dir``; and of the last iteration when the loop
    ends, if it has none yet."""

    def __init__(self) -> None:
        self._last_metrics: dict | None = None
        self._written_at = 0
        """the iteration of the last checkpoint written"""

    def at_iteration_end(self, run: RunState, metrics: dict, verdict: StageVerdict) -> Path | None:
        """The checkpoint of the iteration that just ended (``metrics``, ``verdict``) where
        one is due; returns it (None where none was)."""
        self._last_metrics = metrics
        spec = run.job.checkpoint
        due = run.iteration % spec.every_iters == 0
        if due or recording_due(spec, run.iteration, verdict):
            return self.write(run, metrics)
        return None

    def at_run_end(self, run: RunState) -> None:
        """When the trainer's loop has ended (not after an error): the last iteration's
        checkpoint, if it has none yet."""
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
