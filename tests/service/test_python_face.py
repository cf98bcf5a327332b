"""The Python face at the package top: ``gaitforge.train`` a job (a file or a mapping) into a
run directory, ``gaitforge.evaluate`` it, ``gaitforge.load_policy`` to act in its scene's env;
bad arguments name themselves (real MuJoCo, in-process rollouts)."""

from __future__ import annotations

from pathlib import Path

import gaitforge
import numpy as np
import pytest
from gaitforge.service.ops import InputError
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.spec_io import SpecError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
ELBOW = {
    "name": "elbow-face",
    "stages": [{"scene": "elbow-reach", "env_steps": 400}],
    "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 50},
    "ppo": {"batch_env_steps": 200, "minibatch_size": 50},
}


def test_train_evaluate_and_act_from_python(tmp_path: Path) -> None:
    result = gaitforge.train(ELBOW, tmp_path / "run", seed=3, tensorboard=False)
    assert result.finished and result.env_steps == 400 and result.checkpoint is not None
    report = gaitforge.evaluate(result.run_dir, episodes=2)
    deterministic = report.results["deterministic"]
    assert len(deterministic.episodes) == 2 and report.env_steps == 400
    policy = gaitforge.load_policy(result.checkpoint)
    assert policy.scene.name == "elbow-reach" and policy.meta.job["seed"] == 3
    env = MuscleEnv(policy.scene)
    obs, _ = env.reset(seed=0)
    assert policy.obs_names == env.obs_names
    action = policy(obs)
    assert action.shape == env.action_space.shape and np.isfinite(action).all()
    assert not np.array_equal(policy(obs, deterministic=False), action)


def test_a_job_file_with_overrides_and_a_time_limit(tmp_path: Path) -> None:
    result = gaitforge.train(
        EXAMPLES / "elbow-reach.yaml",
        tmp_path / "run",
        overrides={"workers.num_workers": 0, "ppo.batch_env_steps": 200},
        max_iterations=1,
        tensorboard=False,
    )
    assert result.iterations == 1 and not result.finished


def test_bad_arguments_name_themselves(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"^budget_scale: "):
        gaitforge.train(ELBOW, tmp_path, budget_scale=-1.0)
    with pytest.raises(SpecError, match=r"missing\.yaml"):
        gaitforge.train(tmp_path / "missing.yaml")
    with pytest.raises(ValueError, match=r"no such file or directory"):
        gaitforge.load_policy(tmp_path / "nothing")
