"""Promotion on a stage's deterministic evaluation: ``eval.*`` rules, how they are written and
checked, the verdict they give at an evaluation, and real short runs that promote on one, run
to their budget when one cannot pass (or, with ``if_not_promoted: fail``, end the job saying
which rule fell short and by how much), promote only when fresh episodes confirm the pass,
and end with the network that passed."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.curriculum import CurriculumState, StageShortfallError
from gaitforge.learner.evaluation.episodes import evaluate_policy
from gaitforge.learner.evaluation.stage_judge import (
    CONFIRMATION_SEED,
    EVALUATION_SEED,
    score,
)
from gaitforge.learner.job import Job, PromotionRule, Stage, load_job
from gaitforge.learner.metrics import Episode, evaluation_metrics
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError

BATCH = 256
EVERY = 512
EPISODES = 2
EVALUATED = {"episodes": EPISODES, "every_env_steps": EVERY}


def _stage(promote: object, evaluate: dict | None = EVALUATED) -> Stage:
    raw = {"scene": "elbow-reach", "env_steps": 10_000, "promote": promote}
    return Stage.model_validate(raw if evaluate is None else {**raw, "evaluate": evaluate})


def _evaluation(fall_rate: float, speed: float = 1.0, ret: float = 10.0) -> dict[str, float]:
    """An evaluation's metrics as ``StageJudge.evaluate`` gives them."""
    return {
        "eval_return": ret,
        "eval_distance": 2 * speed,
        "eval_speed": speed,
        "eval_fall_rate": fall_rate,
        "eval_survival": 1.0 - fall_rate,
        "eval_length": 2.0,
    }


# ---- writing the rules -------------------------------------------------------------------


def test_an_evaluation_rule_reads_from_a_string_or_a_mapping() -> None:
    stage = _stage(["eval.fall_rate <= 0.1", {"metric": "eval.speed", "op": ">=", "value": 2}])
    fall, speed = stage.promote
    assert (fall.metric, fall.op, fall.value) == ("eval.fall_rate", "<=", 0.1)
    assert fall.on_evaluation and fall.statistic == "fall_rate"
    assert speed.on_evaluation and speed.statistic == "speed"
    assert str(fall) == "eval.fall_rate <= 0.1 on the stage's evaluation"
    training = _stage("fall_rate <= 0.1 over 50").promote[0]
    assert not training.on_evaluation and training.statistic == "fall_rate"
    assert str(training) == "fall_rate <= 0.1 over 50 episodes"


def test_an_evaluation_rule_is_written_without_a_window_and_reads_back() -> None:
    job = Job.model_validate(
        {
            "name": "judged",
            "stages": [
                {
                    "scene": "elbow-reach",
                    "env_steps": 1000,
                    "evaluate": EVALUATED,
                    "promote": ["eval.fall_rate <= 0.1", "return >= -20 over 50"],
                }
            ],
        }
    )
    written = job.model_dump(mode="json")["stages"][0]["promote"]
    assert written == [
        {"metric": "eval.fall_rate", "op": "<=", "value": 0.1},
        {"metric": "return", "op": ">=", "value": -20.0, "window": 50},
    ]
    assert Job.model_validate(job.model_dump(mode="json")) == job


@pytest.mark.parametrize(
    "promote",
    [
        "eval.fall_rate <= 0.1 over 50",
        {"metric": "eval.fall_rate", "op": "<=", "value": 0.1, "window": 50},
    ],
)
def test_an_evaluation_rule_takes_no_window(promote: object) -> None:
    with pytest.raises(ValueError, match=r"eval\.fall_rate: no 'over <episodes>'"):
        _stage(promote)


def test_an_evaluation_rule_names_a_known_statistic() -> None:
    with pytest.raises(ValueError, match=r"'eval\.return'"):
        _stage("eval.height >= 1")


def test_a_stage_with_evaluation_rules_must_evaluate(tmp_path: Path) -> None:
    job_file = tmp_path / "job.yaml"
    job_file.write_text(
        "name: unjudged\n"
        "stages:\n"
        "  - scene: elbow-reach\n"
        "    env_steps: 1000\n"
        "    promote: ['return >= -20 over 50', 'eval.fall_rate <= 0.1']\n"
    )
    with pytest.raises(SpecError) as raised:
        load_job(job_file)
    message = str(raised.value)
    assert message.startswith(f"{job_file}: stages.0: promote: eval.fall_rate"), message
    assert "needs evaluate:" in message and "\n" not in message


# ---- the verdict ---------------------------------------------------------------------------


def test_an_evaluation_rule_is_judged_only_on_an_evaluation() -> None:
    stage = _stage("eval.fall_rate <= 0.1")
    state = CurriculumState()
    assert state.verdict(stage).text is None, "no evaluation now"
    assert state.verdict(stage, _evaluation(fall_rate=0.2)).text is None
    assert (
        state.verdict(stage, _evaluation(fall_rate=0.05)).text
        == "promoted: eval.fall_rate 0.05 <= 0.1"
    )
    state.stage_env_steps = stage.env_steps
    assert state.verdict(stage).text == "budget spent"
    assert state.verdict(stage, _evaluation(fall_rate=0.2)).text == "budget spent"
    assert state.verdict(stage, _evaluation(fall_rate=0.0)).text.startswith("promoted: ")


def test_training_and_evaluation_rules_must_all_pass_at_an_evaluation() -> None:
    stage = _stage(["speed >= 0.2 over 2", "eval.fall_rate <= 0.1"])
    state = CurriculumState()
    passing = _evaluation(fall_rate=0.0)
    state.episodes.append(Episode(1.0, 3.0, 10.0, False, True))
    assert state.verdict(stage, passing).text is None, "the training window is not full"
    state.episodes.append(Episode(1.0, 0.5, 10.0, False, True))
    assert state.verdict(stage, passing).text is None, "training speed 0.175 < 0.2"
    state.episodes.append(Episode(1.0, 5.0, 10.0, False, True))
    assert state.verdict(stage).text is None, "the training rule passes, but no evaluation now"
    assert state.verdict(stage, _evaluation(fall_rate=0.5)).text is None
    assert state.verdict(stage, passing).text == (
        "promoted: speed 0.275 >= 0.2, eval.fall_rate 0 <= 0.1"
    )


def test_an_evaluation_metric_reads_the_last_evaluation_until_the_stage_ends() -> None:
    state = CurriculumState()
    assert math.isnan(state.window_mean("eval.fall_rate", 100)), "none yet"
    state.evaluation = _evaluation(fall_rate=0.25)
    assert state.window_mean("eval.fall_rate", 100) == 0.25
    assert "evaluation" not in state.to_json(), "in memory only"
    state.advance()
    assert math.isnan(state.window_mean("eval.fall_rate", 100))


def test_the_best_network_counts_evaluation_rules_passed_on_its_evaluation() -> None:
    rules = _stage(["eval.fall_rate <= 0.1", "eval.speed >= 2", "return >= 5 over 10"]).promote
    assert isinstance(rules[0], PromotionRule)
    assert score(_evaluation(fall_rate=0.0, speed=3.0, ret=10.0), rules) == (3, 0.0, 10.0)
    assert score(_evaluation(fall_rate=0.05, speed=1.0, ret=10.0), rules) == (2, -0.05, 10.0)
    assert score(_evaluation(fall_rate=0.5, speed=1.0, ret=1.0), rules) == (0, -0.5, 1.0)


# ---- real runs -----------------------------------------------------------------------------


def test_a_shortfall_names_each_rule_its_figure_and_the_gap() -> None:
    stage = _stage(["eval.fall_rate <= 0.1", "eval.speed >= 2", "speed >= 0.5 over 2"])
    state = CurriculumState(stage=3)
    state.episodes.append(Episode(1.0, 2.0, 10.0, False, True))  # 0.2 m/s
    text = state.shortfall(stage, "run", _evaluation(fall_rate=0.14, speed=2.5))
    assert text == (
        "stage 3 (run) spent its 10,000 env steps without reaching its target: "
        "eval.fall_rate 0.14, not <= 0.1 (short by 0.04); eval.speed 2.5 >= 2: passed; "
        "speed 0.2, not >= 0.5 (short by 0.3)"
    )
    none_yet = CurriculumState().shortfall(stage, "run", {})
    assert "eval.fall_rate: not measured (no evaluation)" in none_yet
    assert "speed: not measured (no finished training episode)" in none_yet


def test_failing_needs_a_target() -> None:
    with pytest.raises(ValueError, match=r"if_not_promoted: fail needs promote: rules"):
        Stage.model_validate({"scene": "elbow-reach", "env_steps": 10, "if_not_promoted": "fail"})


def _job(promote: object, env_steps: int = 4 * BATCH, every: int = EVERY, **stage: object) -> Job:
    """elbow-reach, in-process rollouts (4 envs of 64 steps an update; its episodes last 100
    steps, so the first 4 end in the second update's batch), evaluated after the first
    update, every ``every`` stage env steps and at the end, keeping the best network."""
    return Job.model_validate(
        {
            "name": "elbow-promoted",
            "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 32},
            "ppo": {"batch_env_steps": BATCH, "minibatch_size": 128, "epochs": 2, "lr": 3e-3},
            "network": {"hidden": [16]},
            "stages": [
                {
                    "scene": "elbow-reach",
                    "env_steps": env_steps,
                    "promote": promote,
                    "evaluate": {"episodes": EPISODES, "every_env_steps": every},
                    **stage,
                }
            ],
        }
    )


def _played(policy: ActorCritic, seed: int) -> dict[str, float]:
    """``policy``'s evaluation metrics on elbow-reach, episodes ``seed .. seed + EPISODES - 1``."""
    return evaluation_metrics(
        evaluate_policy(policy, load_scene("elbow-reach"), episodes=EPISODES, seed=seed)
    )


def test_a_stage_promotes_at_its_first_evaluation_once_fresh_episodes_confirm_it(
    tmp_path: Path,
) -> None:
    trainer = Trainer(_job("eval.fall_rate <= 1.0"), tmp_path, tensorboard=False)
    history = trainer.run()
    assert trainer.done
    assert len(history) == 1, "the first evaluation follows the first update"
    (only,) = history
    fall_rate, confirmed = only["eval_fall_rate"], only["confirmation_eval_fall_rate"]
    assert only["verdict"] == (
        f"promoted: eval.fall_rate {fall_rate:.3g} <= 1; confirmed: eval.fall_rate "
        f"{confirmed:.3g} <= 1"
    )
    assert only["stage_env_steps"] == BATCH
    # the confirmation played the promoted network on its own episodes (run iteration 1)
    fresh = _played(trainer.policy, CONFIRMATION_SEED + EPISODES * 1)
    assert only["confirmation_eval_return"] == pytest.approx(fresh["eval_return"])
    again = _played(trainer.policy, EVALUATION_SEED)
    assert only["eval_return"] == pytest.approx(again["eval_return"])
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert meta.metrics["verdict"] == only["verdict"]
    assert (tmp_path / "recordings").is_dir(), "a stage's end is recorded"


@pytest.mark.parametrize(
    "promote",
    [
        "eval.return >= 1000",  # elbow-reach's returns are negative
        ["eval.fall_rate <= 1.0", "return >= 1000 over 1"],  # passes on evaluation alone
    ],
)
def test_a_stage_whose_evaluation_rule_cannot_pass_runs_to_its_budget(
    tmp_path: Path, promote: object
) -> None:
    trainer = Trainer(_job(promote), tmp_path, tensorboard=False)
    history = trainer.run()
    assert trainer.done
    assert [h["verdict"] for h in history] == [None, None, None, "budget spent"]
    evaluated = [h["stage_env_steps"] for h in history if "eval_return" in h]
    assert evaluated == [BATCH, 2 * BATCH, 4 * BATCH], "first update, 512, and the end at 1024"
    assert history[-1]["stage_env_steps"] >= 4 * BATCH


def test_a_pass_that_fresh_episodes_do_not_confirm_does_not_promote(tmp_path: Path) -> None:
    """A one-update stage whose rule lies between its network's return on the evaluation's
    episodes and on the confirmation's: it passes the evaluation, fails the confirmation, and
    the stage ends unpromoted; the network is scored by the worse of the two."""
    probe = Trainer(
        _job("eval.return >= 1e9", env_steps=BATCH), tmp_path / "probe", tensorboard=False
    )
    (probed,) = probe.run()
    evaluated = probed["eval_return"]
    confirmed = _played(probe.policy, CONFIRMATION_SEED + EPISODES * 1)["eval_return"]
    assert evaluated != pytest.approx(confirmed), "the two episode sets differ"
    op = ">=" if evaluated > confirmed else "<="
    job = _job(f"eval.return {op} {(evaluated + confirmed) / 2!r}", env_steps=BATCH)
    (only,) = Trainer(job, tmp_path / "run", tensorboard=False).run()
    assert only["eval_return"] == pytest.approx(evaluated), "the same network as the probe's"
    assert only["confirmation_eval_return"] == pytest.approx(confirmed)
    assert only["verdict"] == "budget spent"
    assert score(only, job.stages[0].promote)[0] == 0, "scored by the failed confirmation"


def test_a_stage_that_must_promote_ends_the_job_at_its_budget(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """``if_not_promoted: fail``: the stage's end is checkpointed, then the run ends with an
    error naming the rule, its figure on the last evaluation and the gap; resumed, the run
    says the stage failed and that nothing is left to train."""
    job = _job("eval.return >= 1000", if_not_promoted="fail")
    trainer = Trainer(job, tmp_path, tensorboard=False)
    with pytest.raises(StageShortfallError) as raised:
        trainer.run()
    message = str(raised.value)
    assert message.startswith("stage 0 (elbow-reach) spent its 1,024 env steps"), message
    assert "eval.return " in message and ", not >= 1000 (short by " in message
    _, meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert meta.metrics["verdict"] == "budget spent"
    assert f"eval.return {meta.metrics['eval_return']:.3g}," in message
    with caplog.at_level(logging.WARNING, logger="gaitforge.learner.run_state"):
        resumed = Trainer(job, tmp_path, tensorboard=False)
    assert resumed.done
    assert "stage 0 (elbow-reach) failed" in caplog.text and "the last stage" in caplog.text


def test_promotion_on_an_evaluation_keeps_the_network_evaluated(tmp_path: Path) -> None:
    """With keep_best, a stage that runs out its budget ends with its best network
    (tests/learner/test_stage_judge.py); one promoted on an evaluation ends with the network
    that passed, even where an earlier one scored better."""
    # evaluated after every update; promoted at the first once 4 episodes have ended
    rules = ["eval.fall_rate <= 1.0", "return >= -1e9 over 4"]
    trainer = Trainer(_job(rules, env_steps=8 * BATCH, every=BATCH), tmp_path, tensorboard=False)
    first = trainer.run(max_iterations=1)
    assert first[0]["verdict"] is None and "eval_return" in first[0], "no episode ended yet"
    # fault injection: the network kept scores above any later one (all rules passed,
    # no falls, an infinite return), so the network promoted is not the stage's best
    trainer.judges[0].best = (len(rules), 0.0, math.inf)
    history = trainer.run()
    assert trainer.done
    last = history[-1]
    assert last["verdict"].startswith("promoted: eval.fall_rate "), last["verdict"]
    assert ", return " in last["verdict"]
    assert last["stage_env_steps"] < 8 * BATCH, "promoted before the budget"
    assert "kept_best_from_env_steps" not in last, "no going back to the best"
    best_state, best_meta = load_checkpoint(latest_checkpoint(tmp_path / "best" / "stage-0"))
    assert best_meta.env_steps == BATCH, "the first network stays the one kept"
    final_state, final_meta = load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"))
    assert final_meta.metrics["verdict"] == last["verdict"]
    assert final_meta.env_steps == last["env_steps"]
    for key, value in trainer.policy.state_dict().items():
        assert torch.equal(final_state[key], value), key
    assert any(not torch.equal(final_state[k], best_state[k]) for k in best_state)
