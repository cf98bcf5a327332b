"""The training loop: checkpoints, resume after SIGKILL, and the same loop over a Ray pool."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import ray
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.job import Job
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.ray_start import start_ray


def elbow_job(num_workers: int = 0, envs: int = 4, batch: int = 200) -> Job:
    """elbow-reach for ever (budget 10^9 steps), a checkpoint every 2 iterations."""
    return Job.model_validate(
        {
            "name": "elbow",
            "stages": [{"scene": "elbow-reach", "env_steps": 10**9}],
            "workers": {"num_workers": num_workers, "envs_per_worker": envs, "fragment_length": 50},
            "ppo": {"batch_env_steps": batch, "minibatch_size": 50},
            "checkpoint": {"every_iters": 2},
        }
    )


TRAIN_FOREVER = """
import sys
from pathlib import Path
from tests.learner.test_trainer import elbow_job
from gaitforge.learner.trainer import Trainer
Trainer(elbow_job(), Path(sys.argv[1]), tensorboard=False).run()
"""


def test_resume_after_sigkill_continues_the_step_count(tmp_path: Path) -> None:
    learner = subprocess.Popen(
        [sys.executable, "-c", TRAIN_FOREVER, str(tmp_path)], cwd=Path(__file__).parents[2]
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            found = latest_checkpoint(tmp_path / "checkpoints")
            if (
                found is not None
                and json.loads((found / "meta.json").read_text())["iteration"] >= 4
            ):
                break
            time.sleep(0.2)
        else:
            raise AssertionError("no checkpoint within 120 s")
    finally:
        os.kill(learner.pid, signal.SIGKILL)
        learner.wait()
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    killed_at, steps_at = meta.iteration, meta.env_steps
    trained_s = meta.metrics["train_s"]
    assert meta.scene_spec().name == "elbow-reach"
    time.sleep(0.5)  # the time between a stop and its resume is not training

    before_resume = time.monotonic()
    resumed = Trainer(elbow_job(), tmp_path, tensorboard=False)
    assert (resumed.iteration, resumed.env_steps) == (killed_at, steps_at)
    assert resumed.optimizer.state_dict()["state"], "the optimizer's moments were restored"
    history = resumed.run(max_iterations=2)
    assert [h["iteration"] for h in history] == [killed_at + 1, killed_at + 2]
    assert [h["policy_lag"] for h in history] == [0.0, 0.0], "in-process: sampled on-policy"
    assert history[0]["env_steps"] == steps_at + 200
    assert trained_s < history[0]["train_s"] < trained_s + (time.monotonic() - before_resume)
    _, final = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert final.iteration == killed_at + 2 and final.env_steps == steps_at + 400


def test_the_loop_runs_over_a_ray_pool(tmp_path: Path) -> None:
    """One actor (2 envs: a batch is two of its fragments), so that the lags below hold
    whatever the timing: with two, one that starts late has its first requests (queued
    before the first weights, dropped) replaced by requests with the newest weights, and a
    later batch holds an on-policy fragment (lags [0, 1, 0.5] were seen under load)."""
    start_ray(num_cpus=2, logging_level="ERROR")  # never a cluster already running
    try:
        history = Trainer(elbow_job(num_workers=1, envs=2), tmp_path).run(max_iterations=3)
    finally:
        ray.shutdown()
    assert [h["env_steps"] for h in history] == [200, 400, 600]
    # the actor keeps two requests queued with the weights of when they were queued: the
    # first batch comes from the first weights, every later one from weights an update old
    lags = [h["policy_lag"] for h in history]
    assert lags == [0.0, 1.0, 1.0], lags
    assert latest_checkpoint(tmp_path / "checkpoints").name == "ckpt-000000000600"
    assert list((tmp_path / "tb").glob("events.out.tfevents.*")), "TensorBoard scalars written"
