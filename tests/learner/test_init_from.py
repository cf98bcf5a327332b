"""``init_from``: a job whose first stage starts from another run's checkpoint (its weights
and observation statistics), checked against the first stage's observation and action."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint, load_policy
from gaitforge.learner.job import BlendSpec, Job, NetworkSpec, load_job
from gaitforge.learner.policy import BlendedPolicy, GaussianPolicy
from gaitforge.learner.trainer import Trainer
from gaitforge.service.jobs.spec import SubmissionError, prepare_submission
from gaitforge.workers.spec_io import SpecError

from tests.learner.test_trainer import elbow_job


def _trained(tmp_path: Path) -> Path:
    Trainer(elbow_job(), tmp_path / "first", tensorboard=False).run(max_iterations=2)
    found = latest_checkpoint(tmp_path / "first" / "checkpoints")
    assert found is not None
    return found


def _job(init_from: Path, scene: str = "elbow-reach", action_std: float | None = None) -> Job:
    raw = elbow_job().model_dump()
    raw["init_from"] = str(init_from)
    raw["stages"][0].update(scene=scene, action_std=action_std)
    return Job.model_validate(raw)


def test_the_first_stage_starts_from_the_checkpoint(tmp_path: Path) -> None:
    source = _trained(tmp_path)
    loaded, _ = load_policy(source)
    trainer = Trainer(_job(source), tmp_path / "second", tensorboard=False)
    obs = torch.randn(64, loaded.obs_dim)
    assert torch.allclose(trainer.policy.mean_action(obs), loaded.mean_action(obs), atol=1e-6)
    assert trainer.env_steps == 0 and trainer.lineage[0]["transition"] == "init_from"
    trainer.run(max_iterations=2)
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "second" / "checkpoints"))
    assert meta.lineage[0].transition == "init_from"
    assert meta.lineage[0].source == str(source) and meta.env_steps == 400
    # a resumed run continues from its own checkpoint, not from init_from again
    resumed = Trainer(_job(source), tmp_path / "second", tensorboard=False)
    assert resumed.env_steps == 400


def test_the_action_noise_may_start_anew(tmp_path: Path) -> None:
    source = _trained(tmp_path)
    loaded, _ = load_policy(source)
    trainer = Trainer(_job(source, action_std=0.25), tmp_path / "second", tensorboard=False)
    obs = torch.randn(64, loaded.obs_dim)
    assert torch.allclose(trainer.policy.mean_action(obs), loaded.mean_action(obs), atol=1e-6)
    assert not torch.allclose(loaded.log_std.exp(), torch.tensor(0.25))
    assert torch.allclose(trainer.policy.log_std.exp(), torch.tensor(0.25))
    raw = elbow_job().model_dump()
    raw["stages"][0]["action_std"] = 0.25
    with pytest.raises(ValueError, match=r"stages\.0\.action_std: .* only a network loaded"):
        Job.model_validate(raw)


def test_the_first_stage_may_grow_a_network_from_the_checkpoint(tmp_path: Path) -> None:
    """As between stages: the checkpoint's network is pi_old of a blend (acting exactly as
    it did at alpha 0)."""
    transition = "blend"
    source = _trained(tmp_path)
    loaded, _ = load_policy(source)
    job = _job(source)
    job.stages[0] = job.stages[0].model_copy(
        update={
            "transition": transition,
            "network": NetworkSpec(hidden=[32, 16]),
            "blend": BlendSpec(ramp_env_steps=400, critic_warmup_env_steps=200, fit_epochs=2),
        }
    )
    trainer = Trainer(Job.model_validate(job.model_dump()), tmp_path / "grown", tensorboard=False)
    trainer.run(max_iterations=1)
    assert [entry["transition"] for entry in trainer.lineage] == ["init_from", transition]
    assert isinstance(trainer.policy, BlendedPolicy)
    assert trainer.policy.old.hidden == loaded.hidden
    trainer.run(max_iterations=3)  # alpha reaches 1: pi_old is dropped
    assert isinstance(trainer.policy, GaussianPolicy) and trainer.policy.hidden == (32, 16)
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "grown" / "checkpoints"))
    assert [entry.transition for entry in meta.lineage] == ["init_from", transition]


def test_a_transition_in_the_first_stage_needs_init_from() -> None:
    raw = elbow_job().model_dump()
    raw["stages"][0] |= {"transition": "blend", "network": {"hidden": [32]}}
    with pytest.raises(ValueError, match=r"stages\.0: .* a transition .* needs init_from"):
        Job.model_validate(raw)


def test_a_checkpoint_of_another_body_is_refused(tmp_path: Path) -> None:
    source = _trained(tmp_path)
    with pytest.raises(ValueError, match=r"init_from: .* acts on 6 entries; stage 0's scene"):
        Trainer(_job(source, scene="stand-2d"), tmp_path / "second", tensorboard=False)


def test_job_file_and_rest_checks_name_init_from(tmp_path: Path) -> None:
    job = tmp_path / "job.yaml"
    job.write_text(
        "name: t\ninit_from: policies/none\nstages:\n  - {scene: elbow-reach, env_steps: 10}\n"
    )
    with pytest.raises(SpecError, match=r"job\.yaml: init_from: 'policies/none': no checkpoint"):
        load_job(job)
    with pytest.raises(SubmissionError) as raised:
        prepare_submission(job.read_text())
    assert any(field == "init_from" for field, _ in raised.value.errors)
