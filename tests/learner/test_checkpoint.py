"""Checkpoints: round trip to identical actions, atomic writes, pruning, loud failures."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import (
    CheckpointError,
    checkpoints,
    latest_checkpoint,
    load_checkpoint,
    save_checkpoint,
)
from gaitforge.learner.policy import GaussianPolicy


def _policy() -> GaussianPolicy:
    torch.manual_seed(0)
    policy = GaussianPolicy(obs_dim=5, act_dim=3)
    policy.norm.update(torch.randn(64, 5) * 3 + 1)
    return policy


def test_round_trip_gives_identical_actions(tmp_path: Path) -> None:
    policy = _policy()
    path = save_checkpoint(tmp_path, 1234, policy.state_dict(), {"stage": "walk-2d"})
    assert path.name == "ckpt-000000001234"
    state, meta = load_checkpoint(path)
    clone = GaussianPolicy(obs_dim=5, act_dim=3)
    clone.load_state_dict(state)
    obs = torch.randn(8, 5)
    torch.testing.assert_close(clone.distribution(obs).mean, policy.distribution(obs).mean)
    torch.testing.assert_close(clone.value(obs), policy.value(obs))
    assert meta["stage"] == "walk-2d" and meta["env_steps"] == 1234
    assert "torch" in meta["versions"]
    assert (path / "normalizer.safetensors").exists()


def test_last_k_and_the_best_are_kept(tmp_path: Path) -> None:
    state = _policy().state_dict()
    for step, score in [(1, 5.0), (2, 9.0), (3, 1.0), (4, 2.0), (5, 3.0)]:
        save_checkpoint(tmp_path, step, state, {"metrics": {"return": score}}, keep_last=2,
                        best_metric="return")  # fmt: skip
    assert [p.name for p in checkpoints(tmp_path)] == [
        "ckpt-000000000002", "ckpt-000000000004", "ckpt-000000000005",
    ]  # fmt: skip
    assert latest_checkpoint(tmp_path).name == "ckpt-000000000005"
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
