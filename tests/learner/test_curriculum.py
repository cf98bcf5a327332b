"""Curriculum: job files validated early with one-line errors, promotion rules, stages that
change only the fidelity, and a stage recorded in metrics and checkpoints."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import checkpoints, load_checkpoint
from gaitforge.learner.curriculum import CurriculumState
from gaitforge.learner.job import Job, PromotionRule, Stage, load_job
from gaitforge.learner.metrics import Episode
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.scenes.profiles import NAMED_PROFILES
from gaitforge.workers.spec_io import SpecError


def test_a_rule_reads_from_a_string() -> None:
    stage = Stage.model_validate(
        {"scene": "walk-2d", "env_steps": 10, "promote": "distance >= 5 over 100"}
    )
    assert stage.promote == [PromotionRule(metric="distance", op=">=", value=5.0, window=100)]
    assert str(stage.promote[0]) == "distance >= 5 over 100 episodes"


def test_the_verdict_needs_a_full_window_then_passes_or_the_budget_ends_it() -> None:
    stage = Stage.model_validate(
        {"scene": "walk-2d", "env_steps": 1000, "promote": "fall_rate <= 0.25 over 4"}
    )
    state = CurriculumState()
    for fell in (False, False, False):
        state.episodes.append(Episode(1.0, 2.0, 10.0, fell, not fell))
    assert state.verdict(stage).text is None, "3 episodes < a window of 4"
    state.episodes.append(Episode(1.0, 0.5, 2.0, True, False))
    assert state.verdict(stage).text == "promoted: fall_rate 0.25 <= 0.25"
    assert state.window_mean("speed", 4) == pytest.approx((0.2 * 3 + 0.25) / 4)
    state.episodes.append(Episode(1.0, 0.5, 2.0, True, False))
    assert state.verdict(stage).text is None
    state.stage_env_steps = 1000
    assert state.verdict(stage).text == "budget spent"
    both = Stage.model_validate(
        {
            "scene": "walk-2d",
            "env_steps": 10**6,
            "promote": ["speed >= 0.2 over 2", "fall_rate <= 0.5 over 2"],
        }
    )
    assert both.promote[1].metric == "fall_rate"
    assert state.verdict(both).text is None, "speed passes, falls 2 of 2 do not"
    state.episodes.append(Episode(1.0, 3.0, 10.0, False, True))
    assert state.verdict(both).text == "promoted: speed 0.275 >= 0.2, fall_rate 0.5 <= 0.5"
    assert CurriculumState.from_json(state.to_json()).to_json() == state.to_json()


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("stages: []", "stages: List should have at least 1 item"),
        ("stages: [{scene: walk-2d, env_steps: 0}]", "stages.0.env_steps: Input should be"),
        (
            "stages: [{scene: walk-2d, env_steps: 9, promote: 'speed > 1'}]",
            "stages.0.promote: expected '<metric> >=|<= <value> [over <episodes>]'",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9, promote: ['speed >= 1', 'height >= 1']}]",
            "stages.0.promote.1.metric: Input should be",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9, scene_set: {control_hz: 30}}]",
            "does not divide the control period 1/30.0 s",
        ),
        ("stages: [{scene: nowhere, env_steps: 9}]", "stages.0.scene: scene 'nowhere': unknown"),
        (
            "stages: [{scene: walk-3d, env_steps: 9}]\nbackend: opensim",
            "stages.0.scene: 'walk-3d' runs on ['mujoco'], not on the job's backend 'opensim'",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9}, {scene: run-2d, env_steps: 9, "
            "network: {hidden: [8]}}]",
            "a new network needs transition blend",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9, scene_set: {fidelity: warp}}]",
            "stages.0.scene_set: scene 'walk-2d': fidelity: unknown profile 'warp'",
        ),
        ("stages: [{scene: walk-2d, env_steps: 9}]\nppo: {lr: -1}", "ppo.lr: Input should be"),
        (
            "stages: [{scene: walk-2d, env_steps: 9, ppo: {lr: 0}}]",
            "stages.0.ppo.lr: Input should be greater than 0",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9, ppo: {epochs: 3}}]",
            "stages.0.ppo.epochs: Extra inputs are not permitted",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9}, {scene: run-2d, env_steps: 9, "
            "transition: blend, network: {hidden: [8]}, action_std: 0.3}]",
            "stages.1: action_std: only with transition continue",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9, action_std: 0.3}]",
            "stages.0.action_std: the first stage starts at network.init_std",
        ),
        (
            "stages: [{scene: walk-2d, env_steps: 9}]\nworkers: {threads: 3}",
            "workers.threads: Extra inputs are not permitted",
        ),
    ],
)
def test_bad_job_files_fail_early_in_one_line(tmp_path: Path, body: str, message: str) -> None:
    path = tmp_path / "job.yaml"
    path.write_text(f"name: j\n{body}\n")
    with pytest.raises(SpecError) as err:
        load_job(path)
    assert message in str(err.value) and "\n" not in str(err.value)
    assert str(path) in str(err.value)


def test_stages_promote_switch_fidelity_and_are_checkpointed(tmp_path: Path) -> None:
    """Stand for one fast stage, promote on a rule that any episode passes, then the same
    scene at the accurate profile (a fidelity curriculum) with its own learning rate, batch
    and its action noise started anew."""
    job = Job.model_validate(
        {
            "name": "fidelity-curriculum",
            "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 100},
            "ppo": {"batch_env_steps": 400, "minibatch_size": 200, "epochs": 1, "lr": 1e-3},
            "stages": [
                {
                    "scene": "stand-2d",
                    "scene_set": {"fidelity": "fast"},
                    "env_steps": 100_000,
                    "promote": "length >= 0 over 2",
                },
                {
                    "scene": "stand-2d",
                    "scene_set": {"fidelity": "accurate"},
                    "env_steps": 400,
                    "ppo": {
                        "lr": 1e-4,
                        "lr_end": 5e-5,
                        "decoupled": True,
                        "batch_env_steps": 800,
                        "minibatch_size": 400,
                    },
                    "action_std": 0.6,
                },
            ],
        }
    )
    assert [job.stage_ppo(i).decoupled for i in (0, 1)] == [False, True]
    assert [job.stage_ppo(i).batch_env_steps for i in (0, 1)] == [400, 800]
    assert [job.stage_ppo(i).minibatch_size for i in (0, 1)] == [200, 400]
    trainer = Trainer(job, tmp_path, tensorboard=False)
    assert [s.profile("mujoco").timestep for s in trainer.scenes] == [0.005, 0.0005]
    history = trainer.run()
    ends = [h for h in history if h["verdict"]]
    assert [h["stage"] for h in ends] == [0, 1]
    assert ends[0]["verdict"].startswith("promoted: length")
    assert ends[0]["env_steps"] < 100_000 and ends[1]["verdict"] == "budget spent"
    # the second stage's budget (400) spent in one update of its own batch (800 env steps)
    assert ends[1]["env_steps"] - ends[0]["env_steps"] == 800
    # the job's learning rate, then the second stage's own schedule (its end: one batch)
    assert all(h["lr"] == pytest.approx(1e-3) for h in history if h["stage"] == 0)
    assert ends[1]["lr"] == pytest.approx(5e-5)
    loaded = [load_checkpoint(p) for p in checkpoints(tmp_path / "checkpoints")]
    metas = [meta for _, meta in loaded]
    assert [m.stage.index for m in metas][-2:] == [0, 1]
    # the network's noise: about its init_std 0.3 to the end of stage 0, 0.6 from stage 1's
    # start (a couple of Adam steps at lr 1e-4 move log std by about 2e-4)
    stds = [weights["log_std"].exp() for weights, _ in loaded[-2:]]
    assert torch.allclose(stds[0], torch.tensor(0.3), atol=0.05)
    assert torch.allclose(stds[1], torch.tensor(0.6), atol=0.01)
    # the checkpoint holds the resolved scene: the concrete profile, and the name it came by
    accurate = NAMED_PROFILES["mujoco"]["accurate"].model_dump(mode="json")
    assert metas[-1].scene["fidelity"] == {"mujoco": accurate}
    assert metas[-1].scene["fidelity_names"] == {"mujoco": "accurate"}
    recordings = sorted(p.name for p in (tmp_path / "recordings").glob("*.mcap"))
    assert len(recordings) == 2, "one MCAP recording at each stage end"
    # a run resumed from the last checkpoint has nothing left to do
    resumed = Trainer(job, tmp_path, tensorboard=False)
    assert resumed.done and resumed.run() == []
