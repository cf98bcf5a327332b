"""A policy trained at one target speed says so when it is evaluated at another: its scene
cannot make it follow the target (``one_pace_note``), on fixed scenes and on the shipped
walker's real evaluation."""

from __future__ import annotations

from pathlib import Path

from gaitforge.learner.evaluation.episodes import one_pace_note
from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint
from gaitforge.workers.scenes import load_scene

WALKER = Path(__file__).resolve().parents[2] / "examples" / "policies" / "walk-2d"


def test_only_a_one_pace_policy_asked_for_another_pace_gets_the_note() -> None:
    walk = load_scene("walk-2d+clock")
    slower = load_scene("walk-2d+clock", {"task.target_speed": 1.0})
    ranged = load_scene("run-2d+clock+speed-range")
    note = one_pace_note(walk, slower, sweep=False)
    assert note is not None and "1.25 m/s" in note and "speed-range" in note
    assert one_pace_note(walk, walk, sweep=True) is not None  # a sweep lowers the target
    assert one_pace_note(walk, ranged, sweep=False) is not None  # a drawn target
    assert one_pace_note(walk, walk, sweep=False) is None
    assert one_pace_note(ranged, load_scene("run-2d+clock"), sweep=True) is None
    assert one_pace_note(load_scene("elbow-reach"), load_scene("elbow-reach"), sweep=False) is None


def test_the_shipped_walker_at_another_target_says_it_keeps_its_pace() -> None:
    asked = evaluate_checkpoint(WALKER, scene_set={"task.target_speed": 1.0}, episodes=1)
    assert len(asked.notes) == 1 and "keeps its pace" in asked.notes[0]
    assert asked.to_dict()["notes"] == asked.notes
    assert evaluate_checkpoint(WALKER, episodes=1).notes == []
