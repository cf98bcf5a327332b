"""A job whose first stage tunes the reflex gait controller with CMA-ES (``optimize``) and
whose second trains PPO on top of it: the search's generations are the stage's
iterations, a stopped run resumes the search where it was, and the PPO stage starts from
the tuned controller."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.cmaes import saved_parameters
from gaitforge.learner.job import Job
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.spec_io import SpecError
from pydantic import ValidationError

SHORT = {"episode_s": 0.3}


def search_then_ppo() -> Job:
    return Job.model_validate(
        {
            "name": "reflex",
            "seed": 3,
            "stages": [
                {
                    "scene": "reflex-walk-3d",
                    "scene_set": SHORT,
                    "env_steps": 10**6,
                    "optimize": {"population": 4, "generations": 3, "episodes": 1},
                },
                {"scene": "reflex-walk-3d", "scene_set": SHORT, "env_steps": 120},
            ],
            "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 30},
            "ppo": {"batch_env_steps": 60, "minibatch_size": 30, "epochs": 1},
            "checkpoint": {"every_iters": 1},
        }
    )


def test_a_search_stage_resumes_and_hands_its_controller_to_ppo(tmp_path: Path) -> None:
    first = Trainer(search_then_ppo(), tmp_path, tensorboard=False)
    first.run(max_iterations=2)
    assert [m["cmaes_generation"] for m in first.history] == [1, 2]
    resumed = Trainer(search_then_ppo(), tmp_path, tensorboard=False)
    resumed.run()
    assert resumed.done
    searched = [m for m in resumed.history if "cmaes_generation" in m]
    assert [m["cmaes_generation"] for m in searched] == [3]  # one more, not three again
    with (tmp_path / "cmaes" / "stage-0" / "progress.csv").open() as f:
        assert [row["generation"] for row in csv.DictReader(f)] == ["1", "2", "3"]
    trained = [m for m in resumed.history if m["stage"] == 1]
    assert trained and sum(m["env_steps"] for m in trained[-1:]) >= 120
    tuned = saved_parameters(tmp_path / "cmaes" / "stage-0")
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert meta.scene["action"]["parameters"] == pytest.approx(tuned, rel=1e-12)


def test_a_search_stage_takes_no_ppo_settings() -> None:
    raw = search_then_ppo().model_dump(mode="json")
    raw["stages"][0]["transition"] = "blend"
    raw["stages"][0]["network"] = {"hidden": [8]}
    with pytest.raises(ValidationError, match="a CMA-ES stage trains no network"):
        Job.model_validate(raw)


def test_a_search_stage_needs_the_reflex_controller(tmp_path: Path) -> None:
    raw = search_then_ppo().model_dump(mode="json")
    raw["stages"][0]["scene"] = "walk-2d"
    raw["stages"][0].pop("scene_set")
    raw["stages"] = raw["stages"][:1]
    with pytest.raises(SpecError, match=r"stages.0.optimize: scene 'walk-2d' .* reflex_gait"):
        Trainer(Job.model_validate(raw), tmp_path, tensorboard=False)


def test_the_residual_on_the_controller_starts_at_nothing(tmp_path: Path) -> None:
    """A job on a reflex controller starts with a network whose mean action is 0.5 (no
    residual) for any observation."""

    trainer = Trainer(search_then_ppo(), tmp_path, tensorboard=False)
    obs = torch.randn(5, trainer.policy.obs_dim) * 3.0
    assert torch.equal(trainer.policy.distribution(obs).mean, torch.full((5, 22), 0.5))
