"""Where a training run is: its network and optimizer, its place in the curriculum, its
iteration and env-step counts, its lineage of networks, and the rollout workers it acts
through. This is what a checkpoint saves (:meth:`RunState.meta`) and what a resumed run
restores (:meth:`RunState.restore`); the trainer's loop and its hooks (``learner.hooks``)
read and change it.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Any

import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint, restore_optimizer
from gaitforge.learner.checkpoint_meta import CheckpointMeta
from gaitforge.learner.curriculum import CurriculumState, StageIO, check_stages
from gaitforge.learner.job import Job, Stage, job_changes
from gaitforge.learner.policy import ActorCritic, GaussianPolicy, build_policy
from gaitforge.learner.ppo import PPO, PPOSettings
from gaitforge.learner.sampling import Rollouts
from gaitforge.learner.stage_verdict import BUDGET_SPENT_TEXT
from gaitforge.learner.transitions import network_from_checkpoint
from gaitforge.workers.fragment import Fragment
from gaitforge.workers.scenes import Scene

logger = logging.getLogger(__name__)

MAX_CHANGES_LOGGED = 6
"""changes of the job at a resume named in its warning; the rest are counted"""


class RunState:
    """The state of ``job``'s run in ``run_dir``: a fresh start (torch seeded with the job's
    seed, the first stage's network built) until :meth:`restore` takes up an ``init_from``
    checkpoint or the run's own latest checkpoint.

    Args:
        job: the validated job.
        run_dir: checkpoints go to ``run_dir/checkpoints``.
        scenes: each stage's resolved scene.
        stop: set to stop waiting for fragments (``Trainer.request_stop``).

    Raises:
        SpecError: the stages' scenes do not fit one policy lineage (``check_stages``).
    """

    def __init__(self, job: Job, run_dir: Path, scenes: list[Scene], stop: threading.Event) -> None:
        self.job = job
        self.run_dir = run_dir
        self.scenes = scenes
        self.io, self.mirrors = check_stages(job, scenes)
        torch.manual_seed(job.seed)
        first = self.io[0]
        network = job.network
        policy = GaussianPolicy(
            len(first.obs_names), len(first.act_names), tuple(network.hidden), network.init_std
        )
        if scenes[0].action.gait:  # a residual on a reflex controller starts at nothing
            policy.act_neutrally()
        self.ppo = self.new_ppo(policy)
        self.obs_names: list[str] = first.obs_names
        """the names the policy observes, in input order"""
        self.curriculum = CurriculumState()
        self.iteration = 0
        """PPO updates done"""
        self.env_steps = 0
        """env steps gathered (control steps summed over all envs)"""
        self._trained_s_before = 0.0
        """s of wall clock the processes before this one trained the run (a resume's)"""
        self._started = time.monotonic()
        self.blend_start = 0
        """stage env steps at which the current stage's blend ramp started"""
        self.lineage: list[dict] = [self.lineage_entry(0, "initial")]
        self.rollouts = Rollouts(job.workers, stop)

    # ---- where the run is -----------------------------------------------------------------

    @property
    def policy(self) -> ActorCritic:
        return self.ppo.policy

    @property
    def optimizer(self) -> torch.optim.Optimizer:
        return self.ppo.optimizer

    @property
    def checkpoint_dir(self) -> Path:
        return self.run_dir / "checkpoints"

    @property
    def done(self) -> bool:
        """Every stage has ended."""
        return self.curriculum.stage >= len(self.job.stages)

    @property
    def stage(self) -> Stage:
        return self.job.stages[self.curriculum.stage]

    @property
    def stage_io(self) -> StageIO:
        return self.io[self.curriculum.stage]

    @property
    def stage_ppo(self) -> PPOSettings:
        """The current stage's PPO settings (the job's, with the stage's own)."""
        return self.job.stage_ppo(self.curriculum.stage)

    @property
    def stage_progress(self) -> float:
        """How far the stage is through its budget: its env steps over its ``env_steps``,
        at most 1."""
        return min(1.0, self.curriculum.stage_env_steps / self.stage.env_steps)

    @property
    def scene(self) -> Scene:
        """The current stage's scene (the last one's once every stage has ended)."""
        return self.scenes[min(self.curriculum.stage, len(self.scenes) - 1)]

    @property
    def backend(self) -> str:
        """The current stage's simulator."""
        return self.job.stage_backend(min(self.curriculum.stage, len(self.job.stages) - 1))

    # ---- changes ----------------------------------------------------------------------------

    def new_ppo(self, policy: ActorCritic) -> PPO:
        """PPO on ``policy`` with a fresh Adam: the critic in a group of its own where any
        stage gives it a learning rate of its own (the same groups all run long, so a
        checkpoint resumes)."""
        stages = range(len(self.job.stages))
        apart = any(self.job.stage_ppo(i).critic_lr is not None for i in stages)
        return PPO(policy, critic_apart=apart, lr=self.job.ppo.lr)

    def count(self, fragment: Fragment) -> None:
        """A gathered fragment: its env steps and finished episodes count in the stage and
        the run."""
        self.curriculum.add(fragment, self.scene)
        self.env_steps += fragment.steps

    def switch_policy(self, policy: ActorCritic, io: StageIO) -> None:
        """Make ``policy`` (observing ``io``'s names) the acting one: a fresh optimizer over
        it, the network sent to the rollout workers."""
        self.ppo = self.new_ppo(policy)
        self.obs_names = io.obs_names
        self.rollouts.set_policy(policy)

    def lineage_entry(self, stage: int, transition: str) -> dict:
        """The lineage's record of the current network: made by ``transition`` into
        ``stage`` at the run's current env steps."""
        return {
            "stage": stage,
            "transition": transition,
            "network": self.policy.describe(),
            "env_steps": self.env_steps,
        }

    @property
    def train_s(self) -> float:
        """s of wall clock the run has trained, from its start (this process's set-up
        included), summed over the processes that trained it: the time between a stop and
        its resume is not counted."""
        return self._trained_s_before + time.monotonic() - self._started

    # ---- checkpoints --------------------------------------------------------------------------

    def meta(self, metrics: dict) -> CheckpointMeta:
        """A checkpoint's metadata for the current network, ``metrics`` the last iteration's."""
        flat = {k: v for k, v in metrics.items() if not isinstance(v, dict)}
        return CheckpointMeta.model_validate(
            {
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
            }
        )

    def restore(self) -> None:
        """Take up the run's latest checkpoint in :attr:`checkpoint_dir`, if any; without
        one, the job's ``init_from`` checkpoint (if set) is the first network."""
        latest = latest_checkpoint(self.checkpoint_dir)
        if latest is None:
            if self.job.init_from is not None:
                self._init_from(Path(self.job.init_from))
            return
        state, meta = load_checkpoint(latest)
        meta.check_resumable(latest)
        self._warn_of_job_changes(meta.job, latest)
        policy = build_policy(meta.network)
        policy.load_state_dict(state)
        self.ppo = self.new_ppo(policy)
        restore_optimizer(self.optimizer, latest)
        self.obs_names = meta.obs_names
        self.iteration, self.env_steps = int(meta.iteration or 0), meta.env_steps
        self._trained_s_before = float(meta.metrics.get("train_s") or 0.0)
        self.curriculum = CurriculumState.from_json(meta.curriculum.model_dump())
        self.blend_start = meta.blend_start
        self.lineage = [entry.model_dump() for entry in meta.lineage]
        verdict = meta.metrics.get("verdict")
        if verdict:  # written at a stage's end, before moving on
            ended = self.stage
            if ended.if_not_promoted == "fail" and verdict == BUDGET_SPENT_TEXT:
                left = len(self.job.stages) - self.curriculum.stage - 1
                logger.warning(
                    "stage %d (%s) failed: it spent its budget without reaching its target; "
                    "%s (to train it longer, resume from a checkpoint before its end with a "
                    "larger env_steps)",
                    self.curriculum.stage,
                    ended.name or ended.scene,
                    f"the run goes on with the next of {left} stage(s)"
                    if left
                    else "it was the last stage: the run has nothing left to train",
                )
            self.curriculum.advance()
        logger.info(
            "resumed from %s: stage %d, iteration %d, %d env steps",
            latest,
            self.curriculum.stage,
            self.iteration,
            self.env_steps,
        )

    def _warn_of_job_changes(self, saved: dict[str, Any] | None, latest: Path) -> None:
        """Log what the job given to a resume changes in the one checkpoint ``latest`` trained
        (a seed or override left out of the command, or a rule changed on purpose): the run
        goes on with the job given."""
        changes = job_changes(saved, self.job.model_dump(mode="json")) if saved else []
        if changes:
            shown = "; ".join(changes[:MAX_CHANGES_LOGGED])
            more = len(changes) - MAX_CHANGES_LOGGED
            logger.warning(
                "resuming %s with a job that differs from the one it trained (%s%s); the run "
                "goes on with the job given",
                latest,
                shown,
                f"; and {more} more" if more > 0 else "",
            )

    def _init_from(self, path: Path) -> None:
        """The first network from checkpoint ``path`` (``job.init_from``; see
        :func:`network_from_checkpoint`), with a fresh optimizer and the lineage naming it."""
        policy, meta = network_from_checkpoint(
            path, self.io[0], self.scenes[0].name, self.job.stages[0].action_std
        )
        self.ppo = self.new_ppo(policy)
        self.lineage = [{**self.lineage_entry(0, "init_from"), "source": str(path)}]
        logger.info("stage 0 starts from %s (job %s, %d env steps)", path, meta.job, meta.env_steps)
