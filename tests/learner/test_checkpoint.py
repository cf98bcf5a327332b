"""Checkpoints: round trip to identical actions, atomic writes, pruning, loud failures, the
metadata model and its versions (a checkpoint of an older main still loads and resumes)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import (
    CheckpointError,
    CheckpointMeta,
    checkpoints,
    latest_checkpoint,
    load_checkpoint,
    load_optimizer_state,
    load_policy,
    read_meta,
    save_checkpoint,
    select_checkpoint,
)
from gaitforge.learner.checkpoint_meta import SCHEMA_VERSION, migrate
from gaitforge.learner.job import Job, load_job
from gaitforge.learner.policy import GaussianPolicy
from gaitforge.learner.trainer import Trainer

FIXTURE = Path(__file__).parents[1] / "fixtures" / "checkpoint-v0"
V0 = FIXTURE / "ckpt-000000000512"
V1 = Path(__file__).parents[1] / "fixtures" / "checkpoint-v1"
SHIPPED = Path(__file__).parents[2] / "examples" / "policies"


def _policy() -> GaussianPolicy:
    torch.manual_seed(0)
    policy = GaussianPolicy(obs_dim=5, act_dim=3)
    policy.norm.update(torch.randn(64, 5) * 3 + 1)
    return policy


def test_round_trip_gives_identical_actions(tmp_path: Path) -> None:
    policy = _policy()
    stage = {"index": 0, "name": "walk-2d", "env_steps": 34}
    path = save_checkpoint(tmp_path, 1234, policy.state_dict(), {"stage": stage})
    assert path.name == "ckpt-000000001234"
    state, meta = load_checkpoint(path)
    clone = GaussianPolicy(obs_dim=5, act_dim=3)
    clone.load_state_dict(state)
    obs = torch.randn(8, 5)
    torch.testing.assert_close(clone.distribution(obs).mean, policy.distribution(obs).mean)
    torch.testing.assert_close(clone.value(obs), policy.value(obs))
    assert meta.stage is not None and meta.stage.name == "walk-2d" and meta.env_steps == 1234
    assert "torch" in meta.versions
    assert json.loads((path / "meta.json").read_text())["schema_version"] == SCHEMA_VERSION
    assert (path / "normalizer.safetensors").exists()


def test_last_k_and_the_best_are_kept(tmp_path: Path) -> None:
    state = _policy().state_dict()
    for step, score in [(1, 5.0), (2, 9.0), (3, 1.0), (4, 2.0), (5, 3.0)]:
        save_checkpoint(
            tmp_path, step, state, {"metrics": {"return": score}}, keep_last=2, best_metric="return"
        )
    assert [p.name for p in checkpoints(tmp_path)] == [
        "ckpt-000000000002",
        "ckpt-000000000004",
        "ckpt-000000000005",
    ]
    assert latest_checkpoint(tmp_path).name == "ckpt-000000000005"
    assert select_checkpoint(tmp_path, "latest") == latest_checkpoint(tmp_path)
    assert select_checkpoint(tmp_path, "best").name == "ckpt-000000000002"
    assert select_checkpoint(tmp_path, "best", "distance") is None, "no checkpoint has it"
    assert not list(tmp_path.glob(".tmp-*")), "no temporary directory is left behind"


def test_a_damaged_file_fails_loudly_naming_it(tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path, 7, _policy().state_dict(), {})
    weights = path / "policy.safetensors"
    data = bytearray(weights.read_bytes())
    data[-5] ^= 0xFF
    weights.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=r"policy\.safetensors: sha256 does not match"):
        load_checkpoint(path)


def test_a_directory_without_manifest_is_not_a_checkpoint(tmp_path: Path) -> None:
    (tmp_path / "ckpt-000000000001").mkdir()
    assert checkpoints(tmp_path) == []
    with pytest.raises(CheckpointError, match=r"manifest\.json: missing"):
        load_checkpoint(tmp_path / "ckpt-000000000001")


def test_the_best_skips_unreadable_and_non_finite_and_ties_go_to_the_newest(
    tmp_path: Path,
) -> None:
    state = _policy().state_dict()
    for step, score in [(1, 4.0), (2, float("nan")), (3, 4.0), (4, 1.0)]:
        save_checkpoint(tmp_path, step, state, {"metrics": {"return": score}}, keep_last=9)
    (tmp_path / "ckpt-000000000004" / "meta.json").write_text("{")
    assert select_checkpoint(tmp_path, "best").name == "ckpt-000000000003"
    with pytest.raises(CheckpointError, match=r"000004/meta\.json: unreadable"):
        read_meta(tmp_path / "ckpt-000000000004")


def test_metadata_is_validated_on_write_and_read(tmp_path: Path) -> None:
    state = _policy().state_dict()
    with pytest.raises(CheckpointError, match="stage"):
        save_checkpoint(tmp_path, 1, state, {"stage": "walk-2d"})
    path = save_checkpoint(tmp_path, 1, state, CheckpointMeta(obs_names=["a", "b"]))
    raw = json.loads((path / "meta.json").read_text())
    (path / "meta.json").write_text(json.dumps({**raw, "schema_version": SCHEMA_VERSION + 1}))
    with pytest.raises(CheckpointError, match="newer than this gaitforge reads"):
        read_meta(path)
    (path / "meta.json").write_text(json.dumps({**raw, "iteration": "many"}))
    with pytest.raises(CheckpointError, match="iteration"):
        read_meta(path)


def test_a_version_0_checkpoint_loads_as_the_current_model() -> None:
    """The fixture was written by main before ``meta.json`` had a schema version."""
    assert "schema_version" not in json.loads((V0 / "meta.json").read_text())
    policy, meta = load_policy(V0)
    assert meta.schema_version == SCHEMA_VERSION and meta.env_steps == 512
    assert meta.iteration == 2 and meta.stage is not None and meta.stage.name == "stand-2d"
    assert meta.backend == "mujoco" and meta.scene_spec().name == "stand-2d"
    assert meta.curriculum is not None and len(meta.curriculum.episodes) == 18
    assert [entry.transition for entry in meta.lineage] == ["initial"]
    assert meta.metric("return") == pytest.approx(19.633, abs=1e-3) and meta.metric("alpha") is None
    assert isinstance(policy, GaussianPolicy) and policy.hidden == (16, 16)
    assert meta.obs_names is not None and len(meta.obs_names) == policy.obs_dim == 61
    assert float(policy.norm.count) >= 512, "the normaliser's statistics came back"
    optimizer = load_optimizer_state(V0)
    assert optimizer is not None and optimizer["param_groups"][0]["lr"] == pytest.approx(3e-4)
    action = policy.mean_action(torch.zeros(1, 61))
    assert action.shape == (1, 18) and torch.isfinite(action).all()


def test_a_version_1_checkpoint_reads_as_its_rewrite_in_the_current_schema() -> None:
    """The fixture is the OpenSim walker as shipped in schema version 1 (an older scene
    layout, scene fields on a stage, retired job fields); read, it is the shipped policy
    rewritten in the current schema: the same scene, the same job, the same weights."""
    assert json.loads((V1 / "meta.json").read_text())["schema_version"] == 1
    old_policy, old = load_policy(V1)
    new_policy, new = load_policy(SHIPPED / "walk-2d-opensim")
    assert old.schema_version == new.schema_version == SCHEMA_VERSION
    assert old.scene_spec() == new.scene_spec()
    assert old.job == new.job and old.job is not None
    stored = json.loads((V1 / "meta.json").read_text())["job"]
    assert "warm_start" in stored["stages"][0] and "init_from_action_std" in stored
    assert "warm_start" not in old.job["stages"][0] and "init_from_action_std" not in old.job
    assert "clone_actor" not in old.job["stages"][0]["blend"]
    obs = torch.randn(4, old_policy.obs_dim)
    assert torch.equal(old_policy.mean_action(obs), new_policy.mean_action(obs)), "same weights"


def test_the_trainer_resumes_from_a_version_0_checkpoint(tmp_path: Path) -> None:
    job, scenes, _ = load_job(FIXTURE / "job.yaml")
    raw = job.model_dump()
    raw["workers"]["num_workers"] = 0
    shutil.copytree(V0, tmp_path / "checkpoints" / V0.name)
    trainer = Trainer(Job.model_validate(raw), tmp_path, scenes, tensorboard=False)
    assert (trainer.iteration, trainer.env_steps) == (2, 512)
    assert len(trainer.curriculum.episodes) == 18
    trainer.run(max_iterations=1)
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert meta.iteration == 3 and meta.env_steps >= 512 + 256
    assert meta.schema_version == SCHEMA_VERSION


def test_an_older_job_is_read_with_its_stage_scene_fields_in_scene_set() -> None:
    """A version-1 job set scene fields on a stage and the loaded network's noise apart;
    read, they are where today's job files write them."""
    stage = {"scene": "walk-2d-clock", "control_hz": 25, "fidelity": None, "env_steps": 9}
    later = {"scene": "run-2d", "action": {"kind": "joint_targets"}, "scene_set": {"x": 1}}
    raw = {"schema_version": 1, "job": {"init_from_action_std": 0.1, "stages": [stage, later]}}
    job = migrate(raw, Path("meta.json"))["job"]
    assert job["stages"][0] == {
        "scene": "walk-2d+clock",
        "scene_set": {"control_hz": 25},
        "env_steps": 9,
        "action_std": 0.1,
    }
    assert job["stages"][1]["scene_set"] == {"action": {"kind": "joint_targets"}, "x": 1}
    assert "init_from_action_std" not in job and raw["job"]["init_from_action_std"] == 0.1
