"""What the trainer does at an iteration's end that runs the policy outside training: the
stage's verdict, judged on deterministic evaluations too (``learner.evaluation.stage_judge``),
and MCAP recordings of the checkpoints (``learner.evaluation.recording``)."""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from gaitforge.learner.evaluation.stage_judge import StageJudge, judged_scene
from gaitforge.learner.hooks import recording_due
from gaitforge.learner.metrics import CONFIRMATION_KEY
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.run_state import RunState
from gaitforge.learner.stage_verdict import Outcome, StageVerdict
from gaitforge.workers.episode import EpisodeRunner
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)


class StageJudging:
    """Where every stage of ``run`` stands after an iteration (:meth:`decide`, the one place
    that says whether a stage goes on, is promoted, has spent its budget or fails), with the
    deterministic evaluations of each stage with ``evaluate`` (:class:`StageJudge`, keeping
    its best network in ``run_dir/best/stage-<i>``): after the stage's first update, every
    ``evaluate.every_env_steps`` and at its end, into the iteration's metrics (``eval_*``).
    Each evaluation judges the stage's promotion rules again, its evaluation rules
    (``eval.*``) on it; where they pass, a confirmation on fresh episodes
    (``confirmation_eval_*``) must pass them too. A ``keep_best`` stage that ends with a
    network worse than its best ends with the best (the verdict's ``kept``), unless it was
    promoted on that evaluation.

    ``judged`` holds the resolved ``evaluate.scene`` of each stage that has one (stage index
    -> scene); the others are judged on their own scene as trained.

    Raises:
        SpecError: a stage's evaluation scene does not fit it.
    """

    def __init__(self, run: RunState, judged: dict[int, Scene]) -> None:
        self.judges = {
            i: StageJudge(
                stage,
                i,
                judged_scene(
                    stage, i, run.scenes[i], run.io[i], run.job.stage_backend(i), judged.get(i)
                ),
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

    def decide(self, run: RunState, metrics: dict) -> StageVerdict:
        """The verdict on ``run``'s stage after the iteration whose ``metrics`` these are:
        on its training figures, then, where an evaluation is due or the stage ends, on its
        evaluation (and confirmation), with the network it ends with. Adds the evaluations'
        metrics and the verdict's text (``verdict``) to ``metrics``."""
        stage, curriculum = run.stage, run.curriculum
        verdict = curriculum.verdict(stage)
        if stage.optimize is not None:  # a CMA-ES stage: its budgets alone end it
            search = stage.optimize
            spent = metrics["cmaes_generation"] >= search.generations or (
                search.minutes is not None and metrics["cmaes_wall_s"] >= 60.0 * search.minutes
            )
            if spent and not verdict.ends:
                verdict = StageVerdict(Outcome.BUDGET_SPENT)
            metrics["verdict"] = verdict.text
            return verdict
        judge = self.judges.get(curriculum.stage)
        if judge is not None and (verdict.ends or judge.due(curriculum.stage_env_steps)):
            verdict = self._evaluated(judge, run, metrics)
        if verdict.outcome is Outcome.BUDGET_SPENT and stage.if_not_promoted == "fail":
            name = metrics["stage_name"]
            verdict = verdict.failed(curriculum.shortfall(stage, name, verdict.ended_with()))
        metrics["verdict"] = verdict.text
        return verdict

    @staticmethod
    def _evaluated(judge: StageJudge, run: RunState, metrics: dict) -> StageVerdict:
        """The verdict at an evaluation of ``run``'s policy: on the evaluation, and where
        its evaluation rules promote on it, on a confirmation on fresh episodes too (the
        stage is promoted only if the rules pass there as well); with the best network kept
        so far where a ``keep_best`` stage ends worse than it."""
        evaluation = judge.evaluate(run.policy, run.curriculum.stage_env_steps)
        metrics.update(evaluation)
        run.curriculum.evaluation = evaluation
        verdict = run.curriculum.verdict(run.stage, evaluation)
        confirmation = None
        if judge.promotes_on_evaluation and verdict.promoted:
            confirmation = judge.confirm(run.policy, run.iteration)
            metrics.update({f"{CONFIRMATION_KEY}{k}": v for k, v in confirmation.items()})
            confirmed = run.curriculum.verdict(run.stage, confirmation)
            verdict = (
                replace(verdict, confirmed=confirmed.figures) if confirmed.promoted else confirmed
            )
        verdict = replace(verdict, evaluation=evaluation, confirmation=confirmation)
        metrics["verdict"] = verdict.text  # the kept network's meta holds it
        kept = judge.judge(run.policy, verdict, metrics, run.meta(metrics), run.env_steps)
        return verdict if kept is None else replace(verdict, kept=kept)


def record_due(run: RunState, verdict: StageVerdict, checkpoint: Path | None) -> Path | None:
    """An MCAP recording of one deterministic episode of ``run``'s policy where one is due
    (each stage's end, and every ``checkpoint.record_every_iters`` iterations), in
    ``run_dir/recordings``, named after ``checkpoint``, the one the iteration wrote
    (``learner.hooks.Checkpoints`` writes one wherever a recording is due). Returns its path,
    or None where none was due or it failed."""
    if not recording_due(run.job.checkpoint, run.iteration, verdict):
        return None
    assert checkpoint is not None, "Checkpoints writes one wherever a recording is due"
    path = run.run_dir / "recordings" / f"{checkpoint.name}-{run.scene.name}.mcap"
    return record_policy(run.policy, run.scene, run.backend, checkpoint, path, run.job.seed)


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
