"""Warm start from recorded excitations: the table and its labels, the job option's checks
(one line naming the file and field), and a real warm start in the trainer on
imitate-walk-2d (MuJoCo): afterwards the policy's deterministic action at phase p is close
to the recorded (CMC) excitations at p."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from gaitforge.learner.clone_excitations import (
    ExcitationError,
    ExcitationTable,
    SideGuess,
    excitation_labels,
    excitation_table,
    mirror_name,
    phases_of,
)
from gaitforge.learner.evaluation.evaluate import make_runner, policy_act
from gaitforge.learner.job import Job, load_job
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.episode import Observer
from gaitforge.workers.motions import load_motion
from gaitforge.workers.spec_io import SpecError

SCENE = "imitate-walk-2d"


def test_the_table_is_periodic_and_linear_between_samples() -> None:
    values = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5], [0.0, 0.0]])
    table = ExcitationTable(["a_r", "a_l"], values)
    np.testing.assert_allclose(
        table.at(np.array([0.0, 0.25, 0.125, 0.875, 1.125])),
        [
            [0.0, 1.0],
            [1.0, 0.0],
            [0.5, 0.5],
            [0.0, 0.5],
            [0.5, 0.5],
        ],
    )
    assert list(table.columns(["a_l", "a_r"])) == [1, 0]
    assert list(table.columns(["a_l", "a_r"], mirrored=True)) == [0, 1]
    assert mirror_name("vasti_r") == "vasti_l" and mirror_name("lumbar") == "lumbar"
    with pytest.raises(ExcitationError, match="b_r"):
        table.columns(["b_r"])


def test_labels_follow_the_observed_phase() -> None:
    table = ExcitationTable(["m_r", "m_l"], np.array([[0.0, 1.0], [1.0, 0.0]]))
    names = ["x", "phase_sin", "phase_cos"]
    phases = np.array([0.0, 0.25, 0.5, 0.75])
    obs = np.column_stack([np.zeros(4), np.sin(2 * math.pi * phases), np.cos(2 * math.pi * phases)])
    np.testing.assert_allclose(phases_of(obs, names), phases, atol=1e-12)
    labels = excitation_labels(obs, names, ["m_r", "m_l"], table)
    np.testing.assert_allclose(labels[:, 0], [0.0, 0.5, 1.0, 0.5], atol=1e-12)
    with pytest.raises(ExcitationError, match="phase"):
        phases_of(obs[:, :1], ["x"])


def test_the_recorded_walk_excitations_cover_the_gait2d_muscles() -> None:
    table = excitation_table("gait2d", "walk")
    assert len(table.muscles) == 18 and table.values.shape[1] == 18
    assert table.values.min() >= 0.0 and table.values.max() <= 1.0
    with pytest.raises(ExcitationError, match="run"):
        excitation_table("gait2d", "run")


def job_file(tmp_path: Path, stage: dict) -> Path:
    job = {
        "name": "warm",
        "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 64},
        "stages": [stage],
    }
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(job))
    return path


def one_line(path: Path) -> str:
    with pytest.raises(SpecError) as caught:
        load_job(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    return message


def test_bad_warm_start_options_are_one_line(tmp_path: Path) -> None:
    line = one_line(
        job_file(
            tmp_path, {"scene": "walk-2d", "env_steps": 10, "warm_start": {"excitations": "walk"}}
        )
    )
    assert "stages.0.warm_start" in line and "imitates no motion" in line
    line = one_line(
        job_file(tmp_path, {"scene": SCENE, "env_steps": 10, "warm_start": {"excitations": "run"}})
    )
    assert "stages.0.warm_start.excitations" in line and "run" in line
    bad = {"excitations": "walk", "rounds": 0}
    line = one_line(job_file(tmp_path, {"scene": SCENE, "env_steps": 10, "warm_start": bad}))
    assert "stages.0.warm_start.rounds" in line
    job, _ = load_job(
        job_file(tmp_path, {"scene": SCENE, "env_steps": 10, "warm_start": {"excitations": "walk"}})
    )
    assert job.stages[0].warm_start is not None


class Phases(Observer):
    """Observer: each step's observation, action (the deterministic excitation) and whether
    the episode is mirrored (as the env says)."""

    def __init__(self) -> None:
        self.obs: list[np.ndarray] = []
        self.actions: list[np.ndarray] = []
        self.mirrored: list[bool] = []
        self.episodes: list[slice] = []
        self._last: np.ndarray | None = None

    def on_reset(self, env, obs, info) -> None:
        self._last = obs
        self.episodes.append(slice(len(self.obs), None))

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.episodes[-1] = slice(self.episodes[-1].start, len(self.obs) + 1)
        self.obs.append(self._last)
        self.actions.append(action)
        self.mirrored.append(bool(info["imitation"]["mirrored"]))
        self._last = obs


def action_error(trainer: Trainer, seeds: range) -> float:
    """Mean absolute difference between the deterministic excitations and the recorded ones
    at each visited observation's phase, over short episodes."""
    policy = trainer.policy
    scene = trainer.scenes[0]
    table = excitation_table("gait2d", "walk")
    watch = Phases()
    with make_runner(policy, scene, "mujoco") as runner:
        for seed in seeds:
            runner.run(policy_act(policy, "deterministic", seed), seed, [watch], max_steps=40)
    obs, mirrored = np.array(watch.obs), np.array(watch.mirrored)
    assert mirrored.any() and not mirrored.all()  # both sides seen
    # the observed joint angles tell the side the env drew: most steps alone, every
    # episode by its summed margin
    sides = SideGuess(load_motion("gait2d", "walk"))
    assert (sides.mirrored(obs, runner.obs_names) == mirrored).mean() > 0.8
    margins = sides.margin(obs, runner.obs_names)
    for episode in watch.episodes:
        assert (margins[episode].sum() > 0) == mirrored[episode][0]
    flag = obs[:, runner.obs_names.index("phase_mirror")]
    np.testing.assert_array_equal(flag > 0, mirrored)  # what the warm start labels by
    labels = excitation_labels(obs, runner.obs_names, runner.act_names, table, mirrored)
    return float(np.abs(np.array(watch.actions) - labels).mean())


def test_the_warm_start_clones_the_recorded_excitations(tmp_path: Path) -> None:
    stage = {
        "scene": SCENE,
        "env_steps": 256,
        "warm_start": {"excitations": "walk", "env_steps": 1024, "rounds": 2, "epochs": 40},
    }
    job = Job.model_validate(
        {
            "name": "warm",
            "seed": 3,
            "network": {"hidden": [64, 64]},
            "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 64},
            "ppo": {"batch_env_steps": 256, "minibatch_size": 256, "epochs": 1, "lr": 1e-6},
            "stages": [stage],
        }
    )
    cold = Trainer(
        job.model_copy(update={"stages": [job.stages[0].model_copy(update={"warm_start": None})]}),
        tmp_path / "cold",
        tensorboard=False,
    )
    before = action_error(cold, range(6))
    torch.manual_seed(0)
    warm = Trainer(job, tmp_path / "warm", tensorboard=False)
    warm.run(max_iterations=1)
    after = action_error(warm, range(6))
    # the warm-up rollouts count in the stage: 2 rounds of 1024 env steps, then the batch
    assert warm.env_steps >= 2 * 1024 + 256
    # an untrained network sends ~0.5 everywhere; the CMC walk's excitations are mostly low
    assert after < 0.5 * before and after < 0.1, (before, after)
