"""bench/job_arms.py: an arm's job is the job file with its overrides, loadable from anywhere."""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

import pytest
import yaml
from gaitforge.learner.job import load_job

REPO = Path(__file__).resolve().parents[2]


def _job_arms():
    spec = importlib.util.spec_from_file_location("job_arms", REPO / "bench" / "job_arms.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


job_arms = _job_arms()

JOB = """
name: arms-test
seed: 7
backend: mujoco
init_from: policies/walk-2d
ppo: {gamma: 0.95}
stages:
  - scene: walk-2d+clock
    env_steps: 1000
    evaluate: {scene: walk-2d, episodes: 2, every_env_steps: 1000}
"""


def test_parse_arm_reads_values_as_yaml_and_names_a_bad_pair():
    assert job_arms.parse_arm(["g", "ppo.gamma=0.99", "init_from_action_std=null"]) == (
        "g",
        {"ppo.gamma": 0.99, "init_from_action_std": None},
    )
    with pytest.raises(SystemExit, match=r"--arm g: 'gamma': expected PATH=VALUE"):
        job_arms.parse_arm(["g", "gamma"])


def test_arm_job_sets_seed_and_overrides_and_loads_from_elsewhere(tmp_path):
    walker = REPO / "examples" / "policies" / "walk-2d"
    (tmp_path / "policies").mkdir()
    (tmp_path / "policies" / "walk-2d").symlink_to(walker)  # the job's relative init_from
    template = tmp_path / "job.yaml"
    template.write_text(JOB)
    (tmp_path / "short.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "walk-2d-clock-2s",
                "base": "walk-2d",
                "options": ["clock"],
                "set": {"episode_s": 2},
            }
        )
    )
    job = job_arms.arm_job(template, 3, {"ppo.gamma": 0.99, "stages.0.scene": "short.yaml"})
    assert job["seed"] == 3 and job["ppo"]["gamma"] == 0.99
    assert job["init_from"] == str(walker.resolve())
    filled = tmp_path / "elsewhere" / "seed-3.yaml"
    filled.parent.mkdir()
    filled.write_text(yaml.safe_dump(job))
    loaded, scenes, _ = load_job(filled)
    assert loaded.seed == 3 and loaded.ppo.gamma == 0.99
    assert [s.name for s in scenes] == ["walk-2d-clock-2s"] and scenes[0].episode_s == 2


def test_judging_scene_is_the_given_one_or_the_last_stages():
    job = {"stages": [{"scene": "walk-2d+clock"}, {"scene": "/jobs/run-fast.yaml"}]}
    assert job_arms.judging_scene(job, "run-2d+clock") == "run-2d+clock"
    assert job_arms.judging_scene(job, "stage") == "/jobs/run-fast.yaml"


def test_arms_run_side_by_side_for_minutes_and_are_judged(tmp_path, monkeypatch):
    """Two arms trained at once (their trainings overlap in time), each stopped by
    --train-minutes long before its budget, each judged, both in arms.json."""
    job = tmp_path / "job.yaml"
    job.write_text(
        "name: tiny\nppo: {batch_env_steps: 256, minibatch_size: 128, epochs: 1}\n"
        "workers: {num_workers: 0}\nstages:\n  - scene: elbow-reach\n    env_steps: 1000000\n"
    )
    monkeypatch.setenv("PATH", f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(
        sys,
        "argv",
        [
            "job_arms",
            str(job),
            "--out",
            str(tmp_path / "out"),
            "--seeds",
            "0",
            "--scene",
            "stage",
            "--judge-seed",
            "5",
            "--episodes",
            "2",
            "--side-by-side",
            "2",
            "--train-minutes",
            "0.001",
            "--arm",
            "control",
            "--arm",
            "lr",
            "ppo.lr=0.0001",
        ],
    )
    job_arms.main()
    report = json.loads((tmp_path / "out" / "arms.json").read_text())
    assert report["train_minutes"] == 0.001 and set(report["arms"]) == {"control", "lr"}
    spans = []
    for arm in ("control", "lr"):
        assert set(report["arms"][arm]["seeds"]["0"]) == {"fall_rate", "speed"}
        run = tmp_path / "out" / arm / "seed-0"
        verdict = json.loads(run.with_suffix(".json").read_text())
        assert (verdict["scene"], verdict["seed"]) == ("elbow-reach", 5), "its stage's scene"
        log = run.with_suffix(".log").read_text()
        assert "iteration 1," in log
        assert len(list((run / "checkpoints").iterdir())) == 1, "stopped after one update"
        # an arm's job file is written as its training starts, its verdict when it is judged:
        # file times, not the log's stamps, which come after each process's imports (seconds
        # apart on a loaded machine even when both processes start together)
        started, judged = (run.with_suffix(suffix).stat().st_mtime for suffix in (".yaml", ".json"))
        spans.append((started, judged))
    (first_start, first_end), (second_start, second_end) = spans
    assert first_start < second_end and second_start < first_end, "ran one after the other"
    assert (
        yaml.safe_load((tmp_path / "out" / "lr" / "seed-0.yaml").read_text())["ppo"]["lr"] == 1e-4
    )
