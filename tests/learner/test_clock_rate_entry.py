"""A network that never paced its clock, carried to a scene whose policy does
(``task.imitate.clock_rate_span``): ``widen_actions`` adds the ``clock_rate`` entry at 0.5
(the clock at its own rate) and leaves the other entries as they were, for ``init_from`` and
for evaluation."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint, load_policy
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint
from gaitforge.learner.job import Job
from gaitforge.learner.policy import GaussianPolicy, widen_actions
from gaitforge.learner.trainer import Trainer
from gaitforge.learner.transitions import network_from_checkpoint
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError

from tests.workers.test_clock_pacing import _paced

RUNNER = Path(__file__).resolve().parents[2] / "examples" / "policies" / "run-2d"


def test_widened_actions_keep_the_old_entries_and_start_the_new_at_one_half() -> None:
    torch.manual_seed(0)
    policy = GaussianPolicy(5, 3, (8, 8), init_std=0.2)
    with torch.no_grad():
        policy.actor[-1].bias.add_(torch.randn(3))
    wider = widen_actions(policy, ["a", "b", "c"], ["a", "x", "b", "c"], new_std=0.1)
    obs = torch.randn(16, 5)
    old, new = policy.distribution(obs), wider.distribution(obs)
    kept = [0, 2, 3]
    assert torch.equal(new.mean[:, kept], old.mean)
    assert torch.equal(new.stddev[:, kept], old.stddev)
    assert torch.equal(new.mean[:, 1], torch.full((16,), 0.5))
    assert new.stddev[0, 1].item() == pytest.approx(0.1)
    assert torch.equal(wider.value(obs), policy.value(obs))
    with pytest.raises(ValueError, match="lost"):
        widen_actions(policy, ["a", "b", "c"], ["a", "b", "x"], new_std=0.1)


def test_init_from_adds_the_clock_rate_to_the_shipped_runner(tmp_path: Path) -> None:
    scene = load_scene(_paced(tmp_path))
    io = StageIO(scene, "mujoco")
    loaded, _ = load_policy(RUNNER)
    policy, _ = network_from_checkpoint(RUNNER, io, scene.name, action_std=0.05,
                                        clock_rate_std=0.15)  # fmt: skip
    assert policy.act_dim == len(io.act_names) == loaded.act_dim + 1
    obs = torch.randn(8, policy.obs_dim)
    with torch.no_grad():
        means = policy.mean_action(obs)
        assert torch.allclose(means[:, :-1], loaded.mean_action(obs))
        assert torch.equal(means[:, -1], torch.full((8,), 0.5))
        assert policy.log_std[:-1].exp() == pytest.approx([0.05] * loaded.act_dim)
        assert policy.log_std[-1].item() == pytest.approx(math.log(0.15))


def test_the_shipped_runner_runs_the_paced_scene_as_the_plain_one(tmp_path: Path) -> None:
    """Evaluated on a paced scene, a network that never paced keeps the clock at its own rate:
    the same episodes as on run-2d+clock (the effort leaves the clock_rate entry out)."""
    paced = evaluate_checkpoint(RUNNER, scene=load_scene(_paced(tmp_path)), episodes=2, seed=1)
    plain = evaluate_checkpoint(RUNNER, scene="run-2d+clock", episodes=2, seed=1)
    for a, b in zip(
        paced.results["deterministic"].episodes, plain.results["deterministic"].episodes,
        strict=True,
    ):  # fmt: skip
        assert (a.distance_m, a.steps, a.fell, a.return_) == (b.distance_m, b.steps, b.fell,
                                                              b.return_)  # fmt: skip
        assert a.effort == pytest.approx(b.effort)


def _two_stages(first: str, second: str, transition: str = "continue") -> Job:
    return Job.model_validate({
        "name": "paced-later",
        "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 50},
        "ppo": {"batch_env_steps": 100, "minibatch_size": 50, "epochs": 1, "mirror": False},
        "network": {"hidden": [16], "init_std": 0.2},
        "stages": [
            {"scene": first, "env_steps": 100},
            {"scene": second, "env_steps": 100, "transition": transition}
            | ({"action_std": 0.05} if transition == "continue" else {"network": {"hidden": [8]}}),
        ],
    })  # fmt: skip


def test_a_later_stage_starts_pacing_with_the_entry_added(tmp_path: Path) -> None:
    """run-2d+clock, then its paced copy: ``continue`` adds ``clock_rate`` at 0.5 with the
    network's init_std (the other entries' noise reset to the stage's action_std), trains
    it and checkpoints it."""
    paced = str(_paced(tmp_path))
    trainer = Trainer(_two_stages("run-2d+clock", paced), tmp_path / "run", tensorboard=False)
    history = trainer.run()
    assert [h["stage"] for h in history if h["verdict"]] == [0, 1]
    weights, meta = load_checkpoint(latest_checkpoint(tmp_path / "run" / "checkpoints"))
    assert meta.network["act_dim"] == 7 and meta.stage.index == 1
    std = weights["log_std"].exp()
    assert std[:-1] == pytest.approx([0.05] * 6, abs=0.002)
    assert std[-1].item() == pytest.approx(0.2, abs=0.005)


def test_pacing_may_start_by_continue_only_and_never_stop(tmp_path: Path) -> None:
    paced = str(_paced(tmp_path))
    with pytest.raises(SpecError, match=r"stages\.1: stage 0's policy paces its clock"):
        Trainer(_two_stages(paced, "run-2d+clock"), tmp_path / "a", tensorboard=False)
    with pytest.raises(SpecError, match="only with transition continue, not blend"):
        Trainer(_two_stages("run-2d+clock", paced, "blend"), tmp_path / "b", tensorboard=False)
