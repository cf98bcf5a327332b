"""A stage judged on deterministic evaluations (learner.evaluation.stage_judge): when they run, what
they report, the best network kept and restored at the stage's end, and bad evaluation
scenes refused before training."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.evaluation.episodes import evaluate_policy
from gaitforge.learner.evaluation.stage_judge import EVALUATION_SEED, score
from gaitforge.learner.job import Job, load_job
from gaitforge.learner.metrics import evaluation_metrics
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError

BATCH = 256
EVERY = 512
EPISODES = 3


def _job(env_steps: int = 4 * BATCH, **evaluate: object) -> Job:
    return Job.model_validate(
        {
            "name": "elbow-judged",
            "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 32},
            "ppo": {"batch_env_steps": BATCH, "minibatch_size": 128, "epochs": 2, "lr": 3e-3},
            "network": {"hidden": [16]},
            "stages": [
                {
                    "scene": "elbow-reach",
                    "env_steps": env_steps,
                    "evaluate": {"episodes": EPISODES, "every_env_steps": EVERY, **evaluate},
                }
            ],
        }
    )


def _evaluated(history: list[dict]) -> list[dict]:
    return [h for h in history if "eval_return" in h]


def test_evaluations_follow_the_first_update_each_interval_and_the_end(tmp_path: Path) -> None:
    trainer = Trainer(_job(env_steps=5 * BATCH), tmp_path, tensorboard=False)
    history = trainer.run()
    stage_steps = [h["stage_env_steps"] for h in _evaluated(history)]
    # first update (256), crossing 512 and 1024, and the stage's end (1280)
    assert stage_steps == [BATCH, 2 * BATCH, 4 * BATCH, 5 * BATCH], stage_steps
    best = latest_checkpoint(tmp_path / "best" / "stage-0")
    assert best is not None, "the best network evaluated is kept as a checkpoint"
    _, meta = load_checkpoint(best)
    assert {"eval_return", "eval_fall_rate", "eval_speed"} <= set(meta.metrics)


def test_the_stage_ends_with_the_best_network_evaluated(tmp_path: Path) -> None:
    trainer = Trainer(_job(), tmp_path, tensorboard=False)
    trainer.run(max_iterations=3)
    # fault injection: the network is wrecked before the stage's last update
    with torch.no_grad():
        for parameter in trainer.policy.trainable_parameters():
            parameter.add_(torch.randn_like(parameter) * 5.0)
    wrecked = {k: v.clone() for k, v in trainer.policy.state_dict().items()}
    history = trainer.run()
    assert trainer.done
    last = history[-1]
    assert last["kept_best_from_env_steps"] < last["env_steps"], "went back to the best"
    # the network the run ends with is the best one kept, not the wrecked one
    final_state, _ = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    best_state, best_meta = load_checkpoint(latest_checkpoint(tmp_path / "best" / "stage-0"))
    for key, value in best_state.items():
        assert torch.equal(final_state[key], value), key
    assert any(not torch.equal(final_state[k], wrecked[k]) for k in wrecked)
    # and it is as good as any evaluated: evaluated again on the same seeds, it scores the best
    again = evaluation_metrics(
        evaluate_policy(
            trainer.policy,
            load_scene("elbow-reach"),
            episodes=EPISODES,
            seed=EVALUATION_SEED,
        )
    )
    scores = [score(h, []) for h in _evaluated(trainer.history)]
    assert score(again, []) == pytest.approx(max(scores))
    # the last network's own evaluation stays in eval_*, the kept one's in kept_eval_*
    assert last["kept_eval_return"] == pytest.approx(again["eval_return"])
    assert score(last, []) < max(scores)
    assert best_meta.env_steps == last["kept_best_from_env_steps"]


def test_without_keep_best_the_stage_ends_with_its_last_network(tmp_path: Path) -> None:
    trainer = Trainer(_job(keep_best=False), tmp_path, tensorboard=False)
    trainer.run(max_iterations=3)
    with torch.no_grad():
        for parameter in trainer.policy.trainable_parameters():
            parameter.add_(torch.randn_like(parameter) * 5.0)
    history = trainer.run()
    assert "kept_best_from_env_steps" not in history[-1]


def test_a_best_network_from_past_the_resume_point_is_dropped(tmp_path: Path) -> None:
    """A resumed run keeps the best network of its past; one from after its last checkpoint
    (here: no checkpoint at all, as when a process dies before its first) is removed, and
    the stage is evaluated after its first update again."""
    best_dir = tmp_path / "best" / "stage-0"
    Trainer(_job(), tmp_path, tensorboard=False).run(max_iterations=2)
    kept = latest_checkpoint(best_dir)
    resumed = Trainer(_job(), tmp_path, tensorboard=False)
    assert resumed.judges[0].best is not None and latest_checkpoint(best_dir) == kept
    shutil.rmtree(tmp_path / "checkpoints")
    fresh = Trainer(_job(), tmp_path, tensorboard=False)
    assert fresh.judges[0].best is None and latest_checkpoint(best_dir) is None
    history = fresh.run(max_iterations=1)
    assert "eval_return" in history[0]


def test_an_evaluation_scene_must_take_the_stage_policy(tmp_path: Path) -> None:
    with pytest.raises(SpecError, match=r"stages\.0\.evaluate\.scene: 'stand-2d' .* other names"):
        Trainer(_job(scene="stand-2d"), tmp_path, tensorboard=False)


def test_a_missing_evaluation_scene_is_named_when_the_job_loads(tmp_path: Path) -> None:
    job_file = tmp_path / "job.yaml"
    job_file.write_text(_job(scene="nowhere.yaml").model_dump_json())
    with pytest.raises(SpecError, match=r"job\.yaml: stages\.0\.evaluate\.scene: "):
        load_job(job_file)


def test_evaluation_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="every_env_steps"):
        _job(every_env_steps=0)
    with pytest.raises(ValueError, match="episodes"):
        _job(episodes=0)
