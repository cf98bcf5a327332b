"""A stage judged on deterministic evaluations, and the best network it evaluated kept.

Training figures judge a stage by its training episodes: stochastic actions, and in an
imitation scene starts along the motion that the mean policy never needs. A stage with
``evaluate`` (``learner.job.StageEvaluation``) is also judged the way ``gaitforge evaluate``
judges a checkpoint: after its first update, every ``every_env_steps`` env steps and at its
end, the trainer runs the mean policy in-process for ``episodes`` episodes of the evaluation
scene (seeds ``EVALUATION_SEED + i``, the same each time, so the networks are compared on the
same initial states; apart from ``gaitforge evaluate``'s default seeds, so that a selection
can be checked on episodes it was not chosen on). The rollout actors go on sampling
meanwhile.

Each evaluation is where the stage's evaluation rules (``promote: eval.fall_rate <= 0.1``)
are judged: the stage is promoted when they pass on it, its training rules pass on their
windows then (``learner.curriculum.CurriculumState.verdict``), and the rules pass again on a
confirmation: as many fresh episodes (seeds ``CONFIRMATION_SEED + episodes * iteration + i``,
a set no other evaluation of the run plays). Networks that pass the fixed set at one of many
evaluations include some that fit its episodes: on episodes nobody picked they fall short
(docs/results/curriculum.md). The confirmation is not chosen on, so it judges the network as
fresh episodes would.

The best network so far is saved as a checkpoint in ``run_dir/best/stage-<i>`` (its
evaluation in ``meta.json``'s metrics, so a resumed run knows what it must beat). With
``keep_best`` the stage ends with that network if it beats the last one: better means more
of the stage's promotion rules passed on the evaluation, then fewer falls, then a higher mean
return, the worse of the evaluation and its confirmation where one ran (:func:`score`); a
stage promoted on an evaluation ends with the network evaluated
then, which passed its rules.
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

from gaitforge.learner.checkpoint import (
    checkpoints,
    latest_checkpoint,
    load_checkpoint,
    save_checkpoint,
)
from gaitforge.learner.checkpoint_meta import CheckpointMeta
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.evaluation.episodes import evaluate_policy
from gaitforge.learner.job import PromotionRule, Stage, StageEvaluation
from gaitforge.learner.metrics import CONFIRMATION_KEY, EVALUATION_KEY, evaluation_metrics
from gaitforge.learner.policy import ActorCritic, build_policy
from gaitforge.learner.stage_verdict import KeptNetwork, StageVerdict
from gaitforge.workers.scenes import Scene
from gaitforge.workers.spec_io import SpecError

logger = logging.getLogger(__name__)

EVALUATION_SEED = 1_000_000
"""episode i of every in-training evaluation resets with this seed + i"""
CONFIRMATION_SEED = 2_000_000
"""episode i of the confirmation at run iteration n resets with this seed + episodes * n + i"""
Score = tuple[int, float, float]
"""(promotion rules passed, -fall rate, mean return): larger is better"""


def score(metrics: dict[str, float], rules: list[PromotionRule]) -> Score:
    """How good an evaluation (``eval_*`` metrics) is for a stage with promotion ``rules``
    (each, training rules too, tested on the evaluation); where a confirmation ran
    (``confirmation_eval_*``), the worse of the two."""
    scores = [_score(metrics, EVALUATION_KEY, rules)]
    if f"{CONFIRMATION_KEY}{EVALUATION_KEY}return" in metrics:
        scores.append(_score(metrics, f"{CONFIRMATION_KEY}{EVALUATION_KEY}", rules))
    return min(scores)


def _score(metrics: dict[str, float], prefix: str, rules: list[PromotionRule]) -> Score:
    passed = sum(rule.passes(metrics[f"{prefix}{rule.statistic}"]) for rule in rules)
    return passed, -metrics[f"{prefix}fall_rate"], metrics[f"{prefix}return"]


def judged_scene(
    stage: Stage,
    index: int,
    trained_scene: Scene,
    trained_io: StageIO,
    backend: str,
    scene: Scene | None,
) -> Scene:
    """The scene stage ``index`` (with ``evaluate``) is judged on: its ``evaluate.scene``,
    resolved where the job was loaded (``scene``; ``learner.job.resolve_scenes``), or the
    stage's own scene as trained (``trained_scene``, whose names are ``trained_io`` on the
    stage's ``backend``).

    Raises:
        SpecError: ``stages.<index>.evaluate.scene`` is missing, or observes or actuates
            other names than the stage's scene.
    """
    assert stage.evaluate is not None
    if stage.evaluate.scene is None:
        return trained_scene
    where = f"stages.{index}.evaluate.scene"
    if scene is None:
        raise SpecError(f"{where}: not resolved with the job (learner.job.resolve_scenes)")
    judged = StageIO(scene, backend)
    if (judged.obs_names, judged.act_names) != (trained_io.obs_names, trained_io.act_names):
        raise SpecError(
            f"{where}: {scene.name!r} on {backend} observes or actuates other names than the "
            f"stage's scene {trained_scene.name!r}; an evaluation scene must take the stage's "
            "policy as it is"
        )
    return scene


class StageJudge:
    """The evaluations of stage ``index`` (which has ``stage.evaluate``) of a run.

    Args:
        stage: the stage; its ``evaluate`` says what, how often and whether to keep the best.
        index: its index in the job.
        scene: the scene it is judged on (:func:`judged_scene`).
        backend: the stage's simulator.
        best_dir: where the best network so far is kept (``run_dir/best/stage-<index>``).
    """

    def __init__(
        self, stage: Stage, index: int, scene: Scene, backend: str, best_dir: Path
    ) -> None:
        assert stage.evaluate is not None
        self.spec: StageEvaluation = stage.evaluate
        self.index = index
        self.rules = stage.promote
        self.backend = backend
        self.best_dir = best_dir
        self.scene = scene
        self.best: Score | None = None
        self._evaluated_at: int | None = None
        """the number of ``every_env_steps`` intervals of the stage at the last evaluation"""

    def resume(self, run_env_steps: int) -> None:
        """Take up the best network kept by an earlier process of this run, which resumes at
        ``run_env_steps`` (0: a fresh start). One kept after that point (the process died
        before its next checkpoint) is from a past the run no longer has: it is removed."""
        saved = latest_checkpoint(self.best_dir)
        if saved is None:
            return
        _, meta = load_checkpoint(saved)
        if meta.env_steps > run_env_steps:
            logger.warning(
                "%s: kept at %d env steps, after the run's resume point (%d); removed",
                saved,
                meta.env_steps,
                run_env_steps,
            )
            shutil.rmtree(self.best_dir, ignore_errors=True)
            return
        self.best = score(meta.metrics, self.rules)

    def due(self, stage_env_steps: int) -> bool:
        """Whether an evaluation is due after the update that brought the stage to
        ``stage_env_steps`` (its first update, then each ``every_env_steps``)."""
        interval = stage_env_steps // self.spec.every_env_steps
        if self._evaluated_at is None and self.best is not None:
            self._evaluated_at = interval  # resumed: the next boundary, not at once
        return self._evaluated_at is None or interval > self._evaluated_at

    def evaluate(self, policy: ActorCritic, stage_env_steps: int) -> dict[str, float]:
        """Run the evaluation of ``policy`` (mean actions); returns its ``eval_*`` metrics."""
        self._evaluated_at = stage_env_steps // self.spec.every_env_steps
        return self._play(policy, EVALUATION_SEED, "evaluation")

    def confirm(self, policy: ActorCritic, iteration: int) -> dict[str, float]:
        """Run the confirmation of ``policy``, which passed its evaluation at run
        ``iteration``, on fresh episodes; returns its ``eval_*`` metrics."""
        seed = CONFIRMATION_SEED + self.spec.episodes * iteration
        return self._play(policy, seed, "confirmation")

    def _play(self, policy: ActorCritic, seed: int, what: str) -> dict[str, float]:
        result = evaluate_policy(
            policy,
            self.scene,
            self.backend,
            episodes=self.spec.episodes,
            seed=seed,
            label=f"{what} on {self.scene.name}",
        )
        return evaluation_metrics(result)

    def offer(
        self, policy: ActorCritic, metrics: dict, meta: CheckpointMeta, env_steps: int
    ) -> bool:
        """Keep ``policy`` (its checkpoint ``meta``, evaluated ``metrics`` and the run's
        ``env_steps``) if it is the best so far; returns whether it was kept."""
        candidate = score(metrics, self.rules)
        if self.best is not None and candidate <= self.best:
            return False
        self.best = candidate
        kept = save_checkpoint(self.best_dir, env_steps, policy.state_dict(), meta)
        for other in checkpoints(self.best_dir):  # one kept, even if older (after a resume)
            if other != kept:
                shutil.rmtree(other, ignore_errors=True)
        return True

    @property
    def promotes_on_evaluation(self) -> bool:
        """The stage has evaluation rules (``eval.*``): it is promoted only at an
        evaluation, on it (and on its confirmation)."""
        return any(rule.on_evaluation for rule in self.rules)

    def judge(
        self,
        policy: ActorCritic,
        verdict: StageVerdict,
        metrics: dict,
        meta: CheckpointMeta,
        env_steps: int,
    ) -> KeptNetwork | None:
        """Keep ``policy``, just evaluated, if it is the best so far (its iteration's
        ``metrics`` hold the evaluation; ``meta`` is its checkpoint's, the run at
        ``env_steps``). At the end of a ``keep_best`` stage (``verdict`` ends it) whose last
        network was not its best, returns the best network to end with (``metrics`` then
        also name it: ``kept_eval_*``, ``kept_best_from_env_steps``); otherwise None, and
        always when the stage was promoted on this evaluation: it ends with the network that
        passed."""
        kept = self.offer(policy, metrics, meta, env_steps)
        if not verdict.ends or not self.spec.keep_best or kept:
            return None
        if self.promotes_on_evaluation and verdict.promoted:
            return None
        best = self.best_network()
        if best is None:
            return None
        network, meta = best
        evaluation = {k: v for k, v in meta.metrics.items() if k.startswith("eval_")}
        # eval_* stay the last network's; kept_eval_* are the network the stage ends with
        metrics.update({f"kept_{k}": v for k, v in evaluation.items()})
        metrics["kept_best_from_env_steps"] = meta.env_steps
        logger.info(
            "stage %d ends with its best evaluated network, from %d env steps",
            self.index,
            meta.env_steps,
        )
        return KeptNetwork(network, meta.env_steps, evaluation)

    def best_network(self) -> tuple[ActorCritic, CheckpointMeta] | None:
        """The best network kept (and its checkpoint's meta), or None if none was."""
        saved = latest_checkpoint(self.best_dir)
        if saved is None:
            return None
        state, meta = load_checkpoint(saved)
        policy = build_policy(meta.network)
        policy.load_state_dict(state)
        return policy, meta
