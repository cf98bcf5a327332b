"""The training loop: PPO through a job's curriculum of stages, with policy blending,
checkpoints, resume after SIGKILL, TensorBoard scalars and a callback for progress displays.

:class:`Trainer` is an on-policy runner (as rsl_rl's ``OnPolicyRunner``): each iteration
samples at least ``ppo.batch_env_steps`` env steps of fragments from the rollout workers
(``learner.sampling.Rollouts``), updates the policy on them (``learner.ppo.PPO``: GAE returns,
on the mirrored batch too with ``ppo.mirror``, then the clipped epochs, then the
normaliser, which must not change before: the behaviour log-probabilities were taken with
the old statistics) and publishes the new weights. Around that, in this order: a blend's
alpha ramps 0 -> 1 over ``blend.ramp_env_steps`` and then collapses to pi_new, before the
weights are published (``learner.hooks.ramp_blend``); at the iteration's end the stage's
verdict is decided in one place (``learner.evaluation.training_hooks.StageJudging.decide``,
a ``learner.stage_verdict.StageVerdict``: goes on, promoted, budget spent or failed; a stage
with ``evaluate`` judged on deterministic evaluations too, and possibly ending with its best
network), the metrics are kept and reported (``learner.hooks.MetricsReport``), a checkpoint
is written every ``checkpoint.every_iters`` iterations and at each stage end
(``learner.hooks.Checkpoints``) and a recording where one is due
(``learner.evaluation.training_hooks.record_due``). Each reads the verdict; none changes it.

The run's state (``learner.run_state.RunState``) is where the curriculum is: when a stage
ends, the next stage's scene is pushed to the live workers and, when the stage is entered,
its transition (``continue`` or ``blend``) builds its network (``learner.transitions``; a
job's ``init_from`` checkpoint is the first stage's pi_old). A blend's warm-up rollouts count
as env steps of the stage, so transitions compare at equal env steps. A stage with
``if_not_promoted: fail`` that spends its budget unpromoted ends the run
(``StageShortfallError``, naming each rule and how far it fell short) once its end's
checkpoint is written; resumed, such a run goes on with the next stage.
``Trainer`` resumes from the newest checkpoint in ``run_dir/checkpoints``.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Any

from gaitforge.learner.cmaes import CmaesTuning, carries, saved_parameters, with_parameters
from gaitforge.learner.curriculum import StageShortfallError
from gaitforge.learner.evaluation.training_hooks import StageJudging, record_due
from gaitforge.learner.hooks import Checkpoints, IterationCallback, MetricsReport, ramp_blend
from gaitforge.learner.job import Job, resolve_scenes
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.run_log import batch_stats, iteration_metrics, search_metrics
from gaitforge.learner.run_state import RunState
from gaitforge.learner.stage_verdict import Outcome, StageVerdict
from gaitforge.learner.transitions import stage_network
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)


def _of_run(name: str) -> Any:
    """The run state's attribute ``name``, read through the trainer."""
    return property(lambda self: getattr(self.state, name), doc=f"``RunState.{name}``")


class Trainer:
    """Runs ``job`` in ``run_dir``; ``history`` holds one metrics dict per iteration.

    Args:
        job: the validated job.
        run_dir: checkpoints go to ``run_dir/checkpoints``, TensorBoard to ``run_dir/tb``,
            recordings to ``run_dir/recordings``, a judged stage's best network to
            ``run_dir/best``.
        scenes: each stage's resolved scene (``learner.job.load_job`` gives them); None
            resolves them (and ``judged``) relative to the working directory.
        judged: stage index -> its resolved evaluation scene, for the stages with
            ``evaluate.scene`` (``load_job`` gives them too).
        on_iteration: called with each iteration's metrics (a progress display).
        tensorboard: write TensorBoard scalars.
    """

    policy: ActorCritic = _of_run("policy")
    optimizer = _of_run("optimizer")
    curriculum = _of_run("curriculum")
    iteration: int = _of_run("iteration")
    env_steps: int = _of_run("env_steps")
    lineage: list[dict] = _of_run("lineage")
    scenes: list[Scene] = _of_run("scenes")
    mirrors = _of_run("mirrors")
    backend: str = _of_run("backend")
    done: bool = _of_run("done")

    def __init__(
        self,
        job: Job,
        run_dir: Path,
        scenes: list[Scene] | None = None,
        judged: dict[int, Scene] | None = None,
        on_iteration: IterationCallback | None = None,
        tensorboard: bool = True,
    ) -> None:
        self.job = job
        self.run_dir = run_dir
        if scenes is None:  # resolved here, on the driver, once
            scenes, judged = resolve_scenes(job)
        self._stop = threading.Event()
        self.state = RunState(job, run_dir, scenes, self._stop)
        self.report = MetricsReport(run_dir / "tb", tensorboard, on_iteration)
        self.judging = StageJudging(self.state, judged or {})
        self.state.restore()
        self.judging.resume(self.state.env_steps)
        self.checkpoints = Checkpoints()
        self._tunings: dict[int, CmaesTuning] = {}
        """stage index -> its CMA-ES search (``optimize`` stages, once entered)"""
        self._carry_searched()

    @property
    def history(self) -> list[dict]:
        return self.report.history

    @property
    def judges(self) -> dict:
        """stage index -> its ``StageJudge`` (stages with ``evaluate``)"""
        return self.judging.judges

    @property
    def on_iteration(self) -> IterationCallback | None:
        return self.report.callback

    @on_iteration.setter
    def on_iteration(self, callback: IterationCallback | None) -> None:
        self.report.callback = callback

    def _carry_searched(self) -> None:
        """After a resume: the tuned controllers of the ``optimize`` stages the run has
        passed (or is in) go on to their later stages again."""
        run = self.state
        for index, stage in enumerate(run.job.stages[: run.curriculum.stage + 1]):
            if stage.optimize is not None:
                tuned = saved_parameters(self._search_dir(index))
                if tuned is not None:
                    self._carry(index, tuned)

    def request_stop(self) -> None:
        """Ask :meth:`run` to stop: the batch being gathered is dropped (its env steps and
        episodes still count), the last update is checkpointed and :meth:`run` returns.
        Safe from a signal handler or another thread."""
        self._stop.set()

    # ---- the loop -------------------------------------------------------------------------

    def run(
        self, max_iterations: int | None = None, max_seconds: float | None = None
    ) -> list[dict]:
        """Train until the last stage ends, or ``max_iterations`` more iterations, or
        ``max_seconds`` of wall-clock time (checked between iterations), or
        :meth:`request_stop` (checked while fragments are awaited too); the last iteration is
        checkpointed."""
        run = self.state
        if run.done:
            return self.history
        run.rollouts.open(run.scene, run.backend, run.policy, self.job.seed * 1000 + run.iteration)
        stop_at = None if max_iterations is None else run.iteration + max_iterations
        deadline = None if max_seconds is None else time.monotonic() + max_seconds
        try:
            while not run.done and (stop_at is None or run.iteration < stop_at):
                if self._stop.is_set():
                    break
                if deadline is not None and time.monotonic() > deadline:
                    break
                try:
                    if not run.curriculum.entered:
                        self._enter_stage()
                    self.iterate()
                except StopRequested:
                    break
            self.checkpoints.at_run_end(run)
        finally:
            run.rollouts.close()
            self.report.close()
        return self.history

    def iterate(self) -> dict:
        """One iteration: a CMA-ES generation in an ``optimize`` stage (:meth:`search`);
        else sample a batch, update the policy on it, ramp a blend, publish the
        new weights; then the stage's verdict (``StageJudging.decide``), the metrics'
        report, the checkpoint and the recording where due, in that order (a checkpoint
        holds its network's evaluation, a recording names its checkpoint); then the next
        stage if this one ended. Returns the iteration's metrics."""
        run = self.state
        if run.stage.optimize is not None:
            return self.search()
        ppo = run.stage_ppo
        start = time.perf_counter()
        fragments = run.rollouts.gather(ppo.batch_env_steps, run.count)
        sampled_s = time.perf_counter() - start
        stats = batch_stats(fragments, run.rollouts.version)
        cfg = ppo.at(run.stage_progress)
        batch = run.ppo.compute_returns(fragments, cfg, run.mirrors[run.curriculum.stage])
        losses = run.ppo.update(batch, fragments, cfg)
        ramp_blend(run)
        run.iteration += 1
        if not self._stop.is_set():  # stopping: no more rollouts (and a local Ray may be gone)
            run.rollouts.publish(run.policy)
        elapsed_s = time.perf_counter() - start
        metrics = iteration_metrics(run, cfg, losses, stats, sampled_s, elapsed_s)
        verdict = self.judging.decide(run, metrics)
        if verdict.kept is not None:
            run.switch_policy(verdict.kept.network, run.stage_io)
        self.report.add(metrics)
        checkpoint = self.checkpoints.at_iteration_end(run, metrics, verdict)
        record_due(run, verdict, checkpoint)
        if verdict.outcome is Outcome.FAILED:
            assert verdict.shortfall is not None
            raise StageShortfallError(verdict.shortfall)
        if verdict.ends:
            self._next_stage(verdict)
        return metrics

    def search(self) -> dict:
        """One CMA-ES generation of the ``optimize`` stage's reflex gait controller
        (``learner.cmaes``), on the rollout actors where the job has a pool, else in this
        process. The stage's scene then carries the search's mean (its checkpoints evaluate
        the controller as tuned so far), and so do the later stages' scenes with the same
        controller: PPO starts on top of it. Then the verdict, report and checkpoint as in
        :meth:`iterate`. Returns the iteration's metrics.

        Raises:
            StopRequested: a stop was requested while candidates were scored (the
                generation is dropped; the search's state is the one before it).
        """
        run = self.state
        index = run.curriculum.stage
        tuning = self._tuning(index)
        start = time.perf_counter()
        generation = tuning.step()
        if generation is None:
            raise StopRequested
        # the search's own count: after a resume from a checkpoint older than its last
        # generation it is ahead of the run's, and the generations between count once
        searched = tuning.saved.env_steps - run.curriculum.stage_env_steps
        run.env_steps += searched
        run.curriculum.stage_env_steps = tuning.saved.env_steps
        run.iteration += 1
        self._carry(index, tuning.tuned_parameters())
        metrics = search_metrics(run, generation, time.perf_counter() - start)
        verdict = self.judging.decide(run, metrics)
        self.report.add(metrics)
        self.checkpoints.at_iteration_end(run, metrics, verdict)
        if verdict.ends:
            tuning.write_tuned()
            self._next_stage(verdict)
        return metrics

    def _tuning(self, index: int) -> CmaesTuning:
        """Stage ``index``'s search (``optimize``), resumed from its folder if it has one."""
        if index not in self._tunings:
            run = self.state
            stage = run.job.stages[index]
            assert stage.optimize is not None
            self._tunings[index] = CmaesTuning(
                run.scenes[index],
                stage.optimize,
                self._search_dir(index),
                run.rollouts.sampler,
                tensorboard=False,  # the run's scalars hold its figures
                seed=run.job.seed,
                stop=self._stop,
            )
        return self._tunings[index]

    def _search_dir(self, index: int) -> Path:
        return self.state.run_dir / "cmaes" / f"stage-{index}"

    def _carry(self, searched: int, tuned: dict[str, float]) -> None:
        """``tuned``, the search of stage ``searched``, into that stage's scene and every
        later stage's with the same controller (their evaluation scenes too)."""
        run = self.state
        origin = run.scenes[searched]
        for index in range(searched, len(run.scenes)):
            if carries(origin, run.scenes[index]):
                run.scenes[index] = with_parameters(run.scenes[index], tuned)
            judge = self.judging.judges.get(index)
            if judge is not None and carries(origin, judge.scene):
                judge.scene = with_parameters(judge.scene, tuned)

    # ---- stages (their networks: learner/transitions.py) ----------------------------------

    def _enter_stage(self) -> None:
        """Build the stage's network (``learner.transitions.stage_network``), mark the stage
        entered and, where its transition made one, name the network in the lineage."""
        run = self.state
        index, stage, io = run.curriculum.stage, run.stage, run.stage_io

        def switch(policy: ActorCritic) -> None:
            run.switch_policy(policy, io)

        def rollout(policy: ActorCritic, env_steps: int) -> list[Fragment]:
            switch(policy)
            return run.rollouts.gather(env_steps, run.count)

        # every network that acted was switched to; the last is the stage's
        run.ppo.policy = stage_network(
            run.policy, run.obs_names, index, self.job, io, switch, rollout
        )
        run.curriculum.entered = True
        if index == 0 and stage.transition == "continue":
            return
        run.blend_start = run.curriculum.stage_env_steps
        run.lineage.append(run.lineage_entry(index, stage.transition))
        logger.info("stage %d (%s): %s", index, run.scene.name, stage.transition)

    def _next_stage(self, verdict: StageVerdict) -> None:
        """The stage ended (``verdict`` says why): the curriculum moves on and the workers
        go on in the next stage's scene."""
        run = self.state
        stage, scene = run.curriculum.stage, run.scene.name
        logger.info("stage %d (%s) ends: %s", stage, scene, verdict.text)
        run.curriculum.advance()
        if not run.done:
            run.rollouts.set_scene(run.scene, run.backend, run.policy)
