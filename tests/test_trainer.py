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

from learner.checkpoint import latest_checkpoint, load_checkpoint
from learner.trainer import TrainConfig, Trainer

TRAIN_FOREVER = """
import sys
from pathlib import Path
from learner.trainer import TrainConfig, Trainer
Trainer(TrainConfig(scene="elbow-reach", run_dir=Path(sys.argv[1]), iterations=10_000,
                    checkpoint_every=2, envs_per_worker=4, fragment_length=50)).run()
"""


def test_resume_after_sigkill_continues_the_step_count(tmp_path: Path) -> None:
    learner = subprocess.Popen([sys.executable, "-c", TRAIN_FOREVER, str(tmp_path)])
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
    killed_at, steps_at = meta["iteration"], meta["env_steps"]
    assert meta["scene"]["name"] == "elbow-reach"

    resumed = Trainer(TrainConfig(scene="elbow-reach", run_dir=tmp_path,
                                  iterations=killed_at + 2, checkpoint_every=2,
                                  envs_per_worker=4, fragment_length=50))  # fmt: skip
    assert (resumed.iteration, resumed.env_steps) == (killed_at, steps_at)
    history = resumed.run()
    assert [h["iteration"] for h in history] == [killed_at + 1, killed_at + 2]
    assert history[0]["env_steps"] == steps_at + 200
    _, final = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert final["iteration"] == killed_at + 2 and final["env_steps"] == steps_at + 400


def test_the_loop_runs_over_a_ray_pool(tmp_path: Path) -> None:
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
    try:
        history = Trainer(TrainConfig(scene="elbow-reach", run_dir=tmp_path, iterations=3,
                                      num_workers=2, envs_per_worker=2, fragment_length=50,
                                      fragments_per_update=2)).run()  # fmt: skip
    finally:
        ray.shutdown()
    assert [h["env_steps"] for h in history] == [200, 400, 600]
    assert latest_checkpoint(tmp_path / "checkpoints").name == "ckpt-000000000600"
