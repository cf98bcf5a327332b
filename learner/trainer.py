"""The training loop: PPO through a job's curriculum of stages, with policy blending,
checkpoints, resume after SIGKILL, TensorBoard scalars and a callback for progress displays.

Each iteration gathers at least ``ppo.batch_env_steps`` env steps of fragments, runs PPO (on
the mirrored batch too with ``ppo.mirror``), then merges the batch's observations into the
normaliser (not before: the behaviour log-probabilities were taken with the old statistics)
and publishes the new weights. After each update the curriculum decides whether the stage is
over (its promotion rule passed or its budget is spent); the next stage's scene is pushed to
the live workers and its transition (``continue``, ``blend``, ``distil``, ``scratch``) builds
its network (``learner.transitions``); a blend's alpha ramps 0 -> 1 over
``blend.ramp_env_steps`` and then collapses to pi_new (a job's ``init_from`` checkpoint is
the first stage's pi_old); then a stage with ``warm_start`` clones a motion's recorded
excitations into the actor's mean, the first stage included. Warm-up rollouts count as env
steps of the stage, so transitions compare at equal env steps. A stage with ``evaluate`` is
judged on deterministic evaluations too, and may end with its best network
(``learner.stage_judge``).
A checkpoint is written every ``checkpoint.every_iters`` iterations and at each stage end;
``Trainer`` resumes from the newest one in ``run_dir/checkpoints``.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from gaitforge.learner.checkpoint import (
    latest_checkpoint,
    load_checkpoint,
    restore_optimizer,
    save_checkpoint,
)
from gaitforge.learner.checkpoint_meta import CheckpointMeta
from gaitforge.learner.curriculum import CurriculumState, StageIO, check_stages
from gaitforge.learner.job import Job, Stage, resolve_scenes
from gaitforge.learner.policy import ActorCritic, BlendedPolicy, GaussianPolicy, build_policy
from gaitforge.learner.ppo import (
    batch_from_fragments,
    optimizer_groups,
    ppo_update,
    set_learning_rates,
)
from gaitforge.learner.run_log import ScalarLog, batch_stats, record_policy
from gaitforge.learner.sampling import Sampler, open_sampler
from gaitforge.learner.stage_judge import StageJudge
from gaitforge.learner.symmetry import add_mirrored
from gaitforge.learner.transitions import (
    collapsed,
    network_from_checkpoint,
    ramp_alpha,
    stage_network,
)
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)

IterationCallback = Callable[[dict], None]


class Trainer:
    """Runs ``job`` in ``run_dir``; ``history`` holds one metrics dict per iteration.

    Args:
        job: the validated job.
        run_dir: checkpoints go to ``run_dir/checkpoints``, TensorBoard to ``run_dir/tb``.
        scenes: each stage's resolved scene (``learner.job.load_job`` gives them); None
            resolves them relative to the working directory.
        on_iteration: called with each iteration's metrics (a progress display).
        tensorboard: write TensorBoard scalars.
    """

    def __init__(
        self,
        job: Job,
        run_dir: Path,
        scenes: list[Scene] | None = None,
        on_iteration: IterationCallback | None = None,
        tensorboard: bool = True,
    ) -> None:
        self.job = job
        self.run_dir = run_dir
        # resolved here, on the driver: actors and checkpoints get concrete fidelity profiles
        self.scenes = [s.resolved() for s in scenes] if scenes is not None else resolve_scenes(job)
        self.on_iteration = on_iteration
        self.io, self.mirrors = check_stages(job, self.scenes)
        torch.manual_seed(job.seed)
        first = self.io[0]
        self.policy: ActorCritic = GaussianPolicy(
            len(first.obs_names), len(first.act_names), tuple(job.network.hidden),
            job.network.init_std,
        )  # fmt: skip
        self.obs_names = first.obs_names
        self.optimizer = self._new_optimizer()
        self.curriculum = CurriculumState()
        self.iteration = 0
        self.env_steps = 0
        self.blend_start = 0
        self.lineage: list[dict] = [self._lineage_entry(0, "initial")]
        self.history: list[dict] = []
        self._min_version = 0  # fragments from older weights are dropped
        self._checkpointed_at = 0
        self._stop = threading.Event()
        self.scalars = ScalarLog(run_dir / "tb", enabled=tensorboard)
        self.judges = {
            i: StageJudge(stage, i, self.scenes[i], self.io[i], job.stage_backend(i),
                          run_dir / "best" / f"stage-{i}")
            for i, stage in enumerate(job.stages) if stage.evaluate is not None
        }  # fmt: skip
        if job.init_from is not None and latest_checkpoint(self.checkpoint_dir) is None:
            self._init_from(Path(job.init_from))
        self._resume()
        for judge in self.judges.values():
            judge.resume(self.env_steps)

    # ---- set-up ---------------------------------------------------------------------------

    @property
    def checkpoint_dir(self) -> Path:
        return self.run_dir / "checkpoints"

    @property
    def stage(self) -> Stage:
        return self.job.stages[self.curriculum.stage]

    @property
    def scene(self) -> Scene:
        return self.scenes[min(self.curriculum.stage, len(self.scenes) - 1)]

    @property
    def backend(self) -> str:
        """The current stage's simulator."""
        return self.job.stage_backend(min(self.curriculum.stage, len(self.job.stages) - 1))

    @property
    def done(self) -> bool:
        return self.curriculum.stage >= len(self.job.stages)

    def _new_optimizer(self) -> torch.optim.Adam:
        """Adam over the policy: the critic in a group of its own where any stage gives it a
        learning rate of its own (the same groups all run long, so a checkpoint resumes)."""
        stages = range(len(self.job.stages))
        apart = any(self.job.stage_ppo(i).critic_lr is not None for i in stages)
        return torch.optim.Adam(optimizer_groups(self.policy, apart), lr=self.job.ppo.lr)

    def _lineage_entry(self, stage: int, transition: str) -> dict:
        """The lineage's record of the current network: made by ``transition`` into
        ``stage`` at the run's current env steps."""
        return {"stage": stage, "transition": transition, "network": self.policy.describe(),
                "env_steps": self.env_steps}  # fmt: skip

    def _policy_factory(self) -> Callable[[], ActorCritic]:
        return functools.partial(build_policy, self.policy.describe())

    def _init_from(self, path: Path) -> None:
        """The first network from checkpoint ``path`` (``job.init_from``; see
        :func:`network_from_checkpoint`), with a fresh optimizer and the lineage naming it."""
        self.policy, meta = network_from_checkpoint(
            path, self.io[0], self.scenes[0].name, self.job.init_from_action_std,
            clock_rate_std=self.job.network.init_std,
        )  # fmt: skip
        self.optimizer = self._new_optimizer()
        self.lineage = [{**self._lineage_entry(0, "init_from"), "source": str(path)}]
        logger.info("stage 0 starts from %s (job %s, %d env steps)", path, meta.job,
                    meta.env_steps)  # fmt: skip

    def _resume(self) -> None:
        latest = latest_checkpoint(self.checkpoint_dir)
        if latest is None:
            return
        state, meta = load_checkpoint(latest)
        meta.check_resumable(latest)
        self.policy = build_policy(meta.network)
        self.policy.load_state_dict(state)
        self.optimizer = self._new_optimizer()
        restore_optimizer(self.optimizer, latest)
        self.obs_names = meta.obs_names
        self.iteration, self.env_steps = int(meta.iteration or 0), meta.env_steps
        self.curriculum = CurriculumState.from_json(meta.curriculum.model_dump())
        self.blend_start = meta.blend_start
        self.lineage = [entry.model_dump() for entry in meta.lineage]
        if meta.metrics.get("verdict"):  # written at a stage's end, before moving on
            self.curriculum.advance()
        logger.info(
            "resumed from %s: stage %d, iteration %d, %d env steps",
            latest, self.curriculum.stage, self.iteration, self.env_steps,
        )  # fmt: skip

    def _make_sampler(self) -> Sampler:
        sampler = open_sampler(
            self.job.workers, self.scene, self.backend, self._policy_factory(),
            seed=self.job.seed * 1000 + self.iteration,
        )  # fmt: skip
        self._min_version = sampler.set_weights(self.policy.state_dict())
        return sampler

    # ---- the loop -------------------------------------------------------------------------

    def request_stop(self) -> None:
        """Ask :meth:`run` to stop: the batch being gathered is dropped (its env steps and
        episodes still count), the last update is checkpointed and :meth:`run` returns.
        Safe from a signal handler or another thread."""
        self._stop.set()

    def run(
        self, max_iterations: int | None = None, max_seconds: float | None = None
    ) -> list[dict]:
        """Train until the last stage ends, or ``max_iterations`` more iterations, or
        ``max_seconds`` of wall-clock time (checked between iterations), or
        :meth:`request_stop` (checked while fragments are awaited too); the last iteration is
        checkpointed."""
        if self.done:
            return self.history
        sampler = self._make_sampler()
        stop_at = None if max_iterations is None else self.iteration + max_iterations
        deadline = None if max_seconds is None else time.monotonic() + max_seconds
        try:
            while not self.done and (stop_at is None or self.iteration < stop_at):
                if self._stop.is_set():
                    break
                if deadline is not None and time.monotonic() > deadline:
                    break
                try:
                    if not self.curriculum.entered:
                        self._enter_stage(sampler)
                    self._iterate(sampler)
                except StopRequested:
                    break
            if self.history and self.history[-1]["iteration"] > self._checkpointed_at:
                self._checkpoint(self.history[-1])
        finally:
            sampler.close()
            self.scalars.close()
        return self.history

    def _gather(self, sampler: Sampler, env_steps: int) -> list[Fragment]:
        """Fragments of the current policy version or newer, at least ``env_steps`` steps;
        every one counts in the stage's episodes and the run's env steps."""
        fragments: list[Fragment] = []
        while sum(f.steps for f in fragments) < env_steps:
            fragment, version = sampler.next_fragment(self.job.workers.timeout_s, self._stop)
            if version < self._min_version:
                continue  # made before a scene or network switch
            fragments.append(fragment)
            self.curriculum.add(fragment, self.scene)
            self.env_steps += fragment.steps
        return fragments

    def _iterate(self, sampler: Sampler) -> None:
        stage, ppo = self.stage, self.job.stage_ppo(self.curriculum.stage)
        start = time.perf_counter()
        fragments = self._gather(sampler, ppo.batch_env_steps)
        gathered_s = time.perf_counter() - start
        stats = batch_stats(fragments, sampler.version)
        obs = np.concatenate([f.flat_obs() for f in fragments])
        progress = min(1.0, self.curriculum.stage_env_steps / stage.env_steps)
        cfg = ppo.at(progress)
        set_learning_rates(self.optimizer, cfg)
        batch = batch_from_fragments(fragments, cfg)
        mirror = self.mirrors[self.curriculum.stage]
        if mirror is not None:
            batch = add_mirrored(batch, mirror, self.policy)
        losses = ppo_update(self.policy, self.optimizer, batch, cfg)
        # after the update: the batch's log-probabilities were taken with the old statistics
        self.policy.norm.update(torch.from_numpy(obs))
        self._ramp_blend(sampler)
        self.iteration += 1
        if not self._stop.is_set():  # stopping: no more rollouts (and a local Ray may be gone)
            sampler.set_weights(self.policy.state_dict())
        verdict = self.curriculum.verdict(stage)
        metrics = self._metrics(stats, losses, cfg.lr, cfg.entropy_coef, gathered_s, start)
        metrics["verdict"] = verdict
        judge = self.judges.get(self.curriculum.stage)
        stage_end = verdict is not None
        if judge is not None and (stage_end or judge.due(self.curriculum.stage_env_steps)):
            self._judge(judge, sampler, metrics, stage_end)
        self.history.append(metrics)
        self.scalars.log(metrics)
        if self.on_iteration is not None:
            self.on_iteration(metrics)
        every = self.job.checkpoint.record_every_iters
        record = verdict is not None or (every > 0 and self.iteration % every == 0)
        if record or self.iteration % self.job.checkpoint.every_iters == 0:
            checkpoint = self._checkpoint(metrics)
            if record:  # a recording names the checkpoint it shows
                path = self.run_dir / "recordings" / f"{checkpoint.name}-{self.scene.name}.mcap"
                record_policy(self.policy, self.scene, self.backend, checkpoint, path,
                              self.job.seed)  # fmt: skip
        if verdict is not None:
            logger.info("stage %d (%s) ends: %s", self.curriculum.stage, self.scene.name, verdict)
            self.curriculum.advance()
            if not self.done:
                sampler.set_scene(self.scene, self.backend)
                self._min_version = sampler.set_weights(self.policy.state_dict())

    # ---- stage transitions (the networks: learner/transitions.py) ----------------------

    def _enter_stage(self, sampler: Sampler) -> None:
        """Build the stage's network (``learner.transitions.stage_network``), mark the stage
        entered and, where its transition made one, name the network in the lineage."""
        index, stage = self.curriculum.stage, self.stage
        io = self.io[index]
        switch = functools.partial(self._switch_policy, sampler, io)

        def rollout(policy: ActorCritic, env_steps: int) -> list[Fragment]:
            switch(policy)
            return self._gather(sampler, env_steps)

        self.policy = stage_network(self.policy, self.obs_names, index, self.job, io, self.scene,
                                    switch, rollout)  # fmt: skip
        self.curriculum.entered = True
        if index == 0 and stage.transition == "continue":
            return
        self.blend_start = self.curriculum.stage_env_steps
        self.lineage.append(self._lineage_entry(index, stage.transition))
        logger.info("stage %d (%s): %s", index, self.scene.name, stage.transition)

    def _switch_policy(self, sampler: Sampler, io: StageIO, policy: ActorCritic) -> None:
        """Make ``policy`` (observing ``io``'s names) the acting one: a fresh optimizer over
        it, its weights published to the rollout workers."""
        self.policy = policy
        self.obs_names = io.obs_names
        self.optimizer = self._new_optimizer()
        self._min_version = sampler.set_policy(self._policy_factory(), self.policy.state_dict())

    def _ramp_blend(self, sampler: Sampler) -> None:
        ramp = self.stage.blend.ramp_env_steps
        if ramp_alpha(self.policy, self.curriculum.stage_env_steps, self.blend_start, ramp):
            self.policy = collapsed(self.policy)  # pi_old no longer acts: drop it
            self._min_version = sampler.set_policy(self._policy_factory(), self.policy.state_dict())

    def _judge(self, judge: StageJudge, sampler: Sampler, metrics: dict, stage_end: bool) -> None:
        """Evaluate the network into ``metrics`` and keep it if it is the stage's best so far;
        at a ``keep_best`` stage's end, go back to the best (``StageJudge.judge``)."""
        best = judge.judge(self.policy, self.curriculum.stage_env_steps, self.env_steps,
                           metrics, self._meta, stage_end)  # fmt: skip
        if best is not None:
            self._switch_policy(sampler, self.io[self.curriculum.stage], best)

    # ---- metrics and checkpoints ----------------------------------------------------------

    def _metrics(self, stats: dict, losses: dict, lr: float, entropy_coef: float,
                 gathered_s: float, start: float) -> dict:  # fmt: skip
        """An iteration's metrics; ``stats`` is the batch's ``batch_stats`` (taken before the
        update, whose new weights would count every fragment one version further behind)."""
        steps = stats.pop("batch_steps")
        return {
            "iteration": self.iteration,
            "env_steps": self.env_steps,
            "stage": self.curriculum.stage,
            "stage_name": self.job.stages[self.curriculum.stage].name or self.scene.name,
            "scene": self.scene.name,
            "stage_env_steps": self.curriculum.stage_env_steps,
            "alpha": float(self.policy.alpha) if isinstance(self.policy, BlendedPolicy) else None,
            "steps_per_s": steps / max(time.perf_counter() - start, 1e-9),
            "sample_steps_per_s": steps / max(gathered_s, 1e-9),
            **self.curriculum.summary(),
            "lr": lr,
            "entropy_coef": entropy_coef,
            **losses,
            **stats,
        }

    def _meta(self, metrics: dict) -> CheckpointMeta:
        """A checkpoint's metadata for the current network, ``metrics`` the last iteration's."""
        flat = {k: v for k, v in metrics.items() if not isinstance(v, dict)}
        return CheckpointMeta.model_validate({
            "iteration": self.iteration,
            "job": self.job.model_dump(mode="json"),
            "config": {"backend": self.backend},
            "scene": self.scene.model_dump(mode="json"),
            "stage": {
                "index": self.curriculum.stage,
                "name": flat["stage_name"],
                "env_steps": self.curriculum.stage_env_steps,
            },
            "curriculum": self.curriculum.to_json(),
            "blend_start": self.blend_start,
            "lineage": self.lineage,
            "network": self.policy.describe(),
            "obs_names": self.obs_names,
            "metrics": flat,
        })  # fmt: skip

    def _checkpoint(self, metrics: dict) -> Path:
        self._checkpointed_at = self.iteration
        return save_checkpoint(
            self.checkpoint_dir, self.env_steps, self.policy.state_dict(), self._meta(metrics),
            keep_last=self.job.checkpoint.keep_last, best_metric="return",
            optimizer_state=self.optimizer.state_dict(),
        )  # fmt: skip
