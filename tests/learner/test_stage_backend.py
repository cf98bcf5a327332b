"""A stage on another simulator (``stages[i].backend``): train on MuJoCo, go on on OpenSim
in the same job, with the same network."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.job import Job, load_job
from gaitforge.learner.policy import GaussianPolicy
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError


def _job() -> Job:
    return Job.model_validate(
        {
            "name": "two-sims",
            "stages": [
                {"scene": "stand-2d", "scene_set": {"control_hz": 25}, "env_steps": 64},
                {
                    "scene": "stand-2d",
                    "scene_set": {"control_hz": 25},
                    "backend": "opensim",
                    "env_steps": 64,
                },
            ],
            "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 16},
            "ppo": {"batch_env_steps": 32, "minibatch_size": 16, "epochs": 1},
            "checkpoint": {"every_iters": 1},
        }
    )


def test_a_stage_moves_to_opensim(tmp_path: Path) -> None:
    trainer = Trainer(_job(), tmp_path, tensorboard=False)
    assert trainer.backend == "mujoco"
    history = trainer.run()
    assert [h["stage"] for h in history] == [0, 0, 1, 1]
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert meta.backend == "opensim" and meta.scene_spec().backends == ["opensim"]
    assert len(meta.lineage) == 2 and meta.lineage[1].transition == "continue"


def test_a_worker_switches_simulator_with_the_scene() -> None:
    scene = load_scene("stand-2d").resolved()
    policy = GaussianPolicy(61, 18)
    worker = RolloutWorker(scene, lambda: policy, backend="mujoco", num_envs=1, fragment_length=4)
    worker.set_scene(scene, "opensim")
    assert worker.envs[0].backend == "opensim"
    fragment = worker.sample(policy.state_dict(), version=0)
    assert np.isfinite(fragment.obs).all()


def test_a_stage_backend_the_scene_lacks_is_named(tmp_path: Path) -> None:
    job = tmp_path / "job.yaml"
    job.write_text("name: t\nstages:\n  - {scene: walk-3d, backend: opensim, env_steps: 10}\n")
    with pytest.raises(
        SpecError,
        match=r"stages\.0\.scene: 'walk-3d' runs on \['mujoco'\], "
        r"not on stages\.0\.backend 'opensim'",
    ):
        load_job(job)
