"""What a resume says changed between the job its checkpoint trained and the job it was given
(``learner.job.job_changes``, on real job dumps): each changed value by its dotted path, old
and new, and a stage list that grew or shrank by its count, not as two whole lists."""

from __future__ import annotations

from typing import Any

from gaitforge.learner.job import Job, job_changes


def dump(*stages: dict[str, Any], **fields: Any) -> dict[str, Any]:
    """A validated job of ``stages`` dumped as a checkpoint keeps it."""
    return Job.model_validate({"name": "changes", "stages": list(stages), **fields}).model_dump(
        mode="json"
    )


STAND = {"name": "stand", "scene": "stand-2d", "env_steps": 1000}
WALK = {"name": "walk", "scene": "walk-2d+clock", "env_steps": 2000}


def test_the_same_job_has_no_changes() -> None:
    assert job_changes(dump(STAND, WALK), dump(STAND, WALK)) == []


def test_each_changed_value_is_named_by_its_path() -> None:
    changes = job_changes(dump(STAND, seed=0), dump({**STAND, "env_steps": 500}, seed=7))
    assert changes == ["seed: 0 -> 7", "stages.0.env_steps: 1000 -> 500"]


def test_a_stage_list_of_another_length_is_said_as_counts() -> None:
    changes = job_changes(dump(STAND, WALK), dump({**STAND, "env_steps": 500}))
    assert changes == [
        "stages: 2 entries -> 1",
        "stages.0.env_steps: 1000 -> 500",
        "stages.1: removed 'walk'",
    ]


def test_an_added_rule_is_said_whole() -> None:
    judged = {**WALK, "evaluate": {"episodes": 10}}
    changes = job_changes(
        dump({**judged, "promote": ["eval.speed >= 1"]}),
        dump({**judged, "promote": ["eval.speed >= 1", "eval.fall_rate <= 0.1"]}),
    )
    assert changes[0] == "stages.0.promote: 1 entries -> 2"
    assert changes[1].startswith("stages.0.promote.1: added {")
    assert "eval.fall_rate" in changes[1]


def test_a_list_of_values_is_said_whole() -> None:
    changes = job_changes(
        dump(STAND, network={"hidden": [64, 64]}), dump(STAND, network={"hidden": [64]})
    )
    assert changes == ["network.hidden: [64, 64] -> [64]"]
