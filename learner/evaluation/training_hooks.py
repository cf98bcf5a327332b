"""The trainer's hooks that run the policy outside training: stage judging on deterministic
evaluations (``learner.evaluation.stage_judge``) and MCAP recordings of the checkpoints
(``learner.evaluation.recording``)."""

from __future__ import annotations

import logging
from pathlib import Path

from gaitforge.learner.curriculum import PROMOTED
from gaitforge.learner.evaluation.stage_judge import CONFIRMATION_PREFIX, StageJudge
from gaitforge.learner.hooks import Checkpoints, TrainingHook, recording_due
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.run_state import RunState
from gaitforge.workers.episode import EpisodeRunner
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)


class StageJudging(TrainingHook):
    """The deterministic evaluations of every stage of ``run`` with ``evaluate``
    (:class:`StageJudge`, keeping its best network in ``run_dir/best/stage-<i>``): after the
    stage's first update, every ``evaluate.every_env_steps`` and at its end, into the
    iteration's metrics (``eval_*``). Each evaluation judges the stage's promotion rules again,
    its evaluation rules (``eval.*``) on it, into ``metrics["verdict"]``; where they pass, a
    confirmation on fresh episodes (``confirmation_eval_*``) must pass them too. A ``keep_best``
    stage that ends with a network worse than its best goes on from the best, unless it was
    promoted on that evaluation.

    Raises:
        SpecError: a stage's ``evaluate.scene`` does not fit it.
    """

    def __init__(self, run: RunState) -> None:
        self.judges = {
            i: StageJudge(
                stage,
                i,
                run.scenes[i],
                run.io[i],
                run.job.stage_backend(i),
                run.run_dir / "best" / f"stage-{i}",
            )
            for i, stage in enumerate(run.job.stages)
            if stage.evaluate is not None
        }
        """stage index -> its judge"""

    def resume(self, run_env_steps: int) -> None:
        """Take up the best networks an earlier process of the run kept (which resumes at
        ``run_env_steps``; see :meth:`StageJudge.resume`)."""
        for judge in self.judges.values():
            judge.resume(run_env_steps)

    def on_iteration_end(self, run: RunState, metrics: dict) -> None:
        judge = self.judges.get(run.curriculum.stage)
        stage_end = metrics["verdict"] is not None
        if judge is None or not (stage_end or judge.due(run.curriculum.stage_env_steps)):
            return
        evaluation = judge.evaluate(run.policy, run.curriculum.stage_env_steps)
        metrics.update(evaluation)
        run.curriculum.evaluation = evaluation
        metrics["verdict"] = run.curriculum.verdict(run.stage, evaluation)
        if judge.promoted_on_evaluation(metrics["verdict"]):
            self._confirm(judge, run, metrics)
        best = judge.judge(run.policy, metrics, run.meta(metrics), run.env_steps)
        if best is not None:
            run.switch_policy(best, run.stage_io)

    @staticmethod
    def _confirm(judge: StageJudge, run: RunState, metrics: dict) -> None:
        """Play ``run``'s policy, which passed its evaluation, on fresh episodes; the stage is
        promoted only if the rules pass there too (``metrics``' verdict then names both)."""
        passed = metrics["verdict"]
        confirmation = judge.confirm(run.policy, run.iteration)
        metrics.update({f"{CONFIRMATION_PREFIX}{k}": v for k, v in confirmation.items()})
        confirmed = run.curriculum.verdict(run.stage, confirmation)
        if judge.promoted_on_evaluation(confirmed):
            metrics["verdict"] = f"{passed}; confirmed: {confirmed.removeprefix(PROMOTED)}"
            return
        metrics["verdict"] = confirmed


class Recordings(TrainingHook):
    """An MCAP recording of one deterministic episode of the policy at each stage's end and
    every ``checkpoint.record_every_iters`` iterations, in ``run_dir/recordings``, named
    after the checkpoint it shows (``checkpoints`` writes one wherever a recording is due)."""

    def __init__(self, checkpoints: Checkpoints) -> None:
        self.checkpoints = checkpoints

    def on_iteration_end(self, run: RunState, metrics: dict) -> None:
        if not recording_due(run.job.checkpoint, run.iteration, metrics["verdict"]):
            return
        checkpoint = self.checkpoints.written
        assert checkpoint is not None, "Checkpoints writes one wherever a recording is due"
        path = run.run_dir / "recordings" / f"{checkpoint.name}-{run.scene.name}.mcap"
        record_policy(run.policy, run.scene, run.backend, checkpoint, path, run.job.seed)


def record_policy(
    policy: ActorCritic, scene: Scene, backend: str, checkpoint: Path, path: Path, seed: int
) -> Path | None:
    """One deterministic episode of ``policy`` on ``scene`` as MCAP at ``path``, with the
    checkpoint it shows named in the metadata (the episode loop of ``workers.episode``, the
    recorder its observer). A failure is logged, never raised: a recording must not stop
    training."""
    from gaitforge.learner.evaluation.episodes import policy_act
    from gaitforge.learner.evaluation.recording import (  # lazy: foxglove
        EpisodeRecorder,
        checkpoint_metadata,
    )

    try:
        with EpisodeRunner(scene, backend) as runner:
            recorder = EpisodeRecorder(path, runner.env, checkpoint_metadata(checkpoint))
            summary = runner.run(policy_act(policy, "deterministic", seed), seed, [recorder])
    except Exception:
        logger.exception("recording %s failed; training goes on", path)
        return None
    logger.info("recorded %s: %.2f m in %.1f s", path, summary.distance_m, summary.sim_time_s)
    return path
