"""The job entry as a real process on a tiny in-process job: phase ``starting`` at once, then
progress.json and metrics.jsonl every iteration, a checkpoint and the final evaluation;
the cancel file and SIGTERM stop it with a checkpoint that loads; a failure at run time
ends in phase ``failed`` with its error and exit code 1; the log is appended across
attempts."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.progress import JobProgress, read_metrics, read_progress
from gaitforge.service.jobs.spec import prepare_submission, write_job_files

T = TypeVar("T")
Finished = tuple[JobLayout, int, str, JobProgress]
"""the finished job's layout, exit code, output, and the first progress seen"""
JOB = """name: tiny
ppo: {{batch_env_steps: 256, minibatch_size: 128, epochs: 1}}
workers: {{num_workers: 0, envs_per_worker: 2, fragment_length: 64}}
checkpoint: {{every_iters: 2}}
stages:
  - scene: stand-2d
    scene_set: {{control_hz: 25}}
    env_steps: {env_steps}
    promote: "survival >= 0.95 over 20"
"""


def _layout(root: Path, env_steps: int, job_id: str = "j-0123456789ab") -> JobLayout:
    layout = JobLayout(root, job_id)
    write_job_files(layout, prepare_submission(JOB.format(env_steps=env_steps)))
    return layout


def _start(layout: JobLayout, *args: str) -> subprocess.Popen:
    command = [
        sys.executable,
        "-m",
        "gaitforge.service.jobs.entry",
        "--job-dir",
        str(layout.dir),
        "--evaluate-episodes",
        "1",
        *args,
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "GAITFORGE_JOB_ID": layout.job_id}
    return subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env
    )


def _finish(proc: subprocess.Popen, timeout_s: float = 240) -> tuple[int, str]:
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out


def _wait_for(check: Callable[[], T], timeout_s: float, what: str) -> T:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if found := check():
            return found
        time.sleep(0.05)
    pytest.fail(f"no {what} within {timeout_s} s")


def _video_works() -> bool:
    from gaitforge.learner.evaluation.video import osmesa_available

    return osmesa_available() is None


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Finished:
    """A job of 4 iterations run to its end (with a video where rendering works)."""
    layout = _layout(tmp_path_factory.mktemp("artifacts"), env_steps=1024)
    proc = _start(layout, *([] if _video_works() else ["--no-video"]))
    first = _wait_for(lambda: read_progress(layout.progress_file), 30, "progress.json")
    rc, out = _finish(proc)
    return layout, rc, out, first


def test_a_job_trains_reports_and_is_evaluated(finished: Finished) -> None:
    layout, rc, out, first = finished
    assert rc == 0, out
    assert first.phase == "starting" and first.pid > 0 and first.iteration == 0
    progress = read_progress(layout.progress_file)
    assert progress.phase == "finished" and progress.error is None, out
    assert (progress.iteration, progress.env_steps) == (4, 1024)
    assert progress.checkpoint == "ckpt-000000001024" == layout.checkpoint_names()[-1]
    stage = progress.stage
    assert (stage.index, stage.name, stage.count, stage.budget_env_steps) == (
        0,
        "stand-2d",
        1,
        1024,
    )
    rule = stage.promote[0]
    assert (rule.metric, rule.op, rule.target, rule.window) == ("survival", ">=", 0.95, 20)
    assert rule.value is not None and 0 <= rule.value <= 1 and rule.passing is False
    for key in ("return", "speed", "fall_rate", "survival", "reward_terms", "health", "lr"):
        assert key in progress.metrics, key

    def no_nan(text: str) -> None:
        raise AssertionError(f"non-finite {text} in metrics.jsonl")

    lines = layout.metrics_file.read_text().splitlines()
    rows = [json.loads(line, parse_constant=no_nan) for line in lines]
    assert [r["iteration"] for r in rows] == [1, 2, 3, 4] and rows == read_metrics(
        layout.metrics_file
    )
    assert rows[-1]["verdict"] == "budget spent" and "alive" in rows[-1]["reward_terms"]

    report = json.loads((layout.reports_dir / "evaluate-ckpt-000000001024.json").read_text())
    assert len(report["results"]["deterministic"]["episodes"]) == 1
    # file names relative to the job's folder: a served report shows no server directories
    assert report["checkpoint"] == "run/checkpoints/ckpt-000000001024"
    assert report["recording"] == "evaluation/ckpt-000000001024.mcap"
    names = [p.name for p in layout.recording_files()]
    assert "ckpt-000000001024.mcap" in names
    assert ("ckpt-000000001024.mp4" in names) == _video_works()
    log = layout.log_file.read_text()
    assert "trainer process" in log and "evaluation report" in log and "finished" in log
    assert "evaluating ckpt-000000001024" in out  # the same lines on stdout


def test_a_finished_job_started_again_only_evaluates(finished: Finished) -> None:
    layout = finished[0]
    rc, out = _finish(_start(layout, "--no-video"))
    assert rc == 0, out
    assert read_progress(layout.progress_file).phase == "finished"
    assert len(read_metrics(layout.metrics_file)) == 4  # no more iterations
    assert layout.log_file.read_text().count("trainer process") == 2  # appended


@pytest.mark.parametrize("how", ["cancel", "sigterm"])
def test_cancel_or_sigterm_stops_with_a_checkpoint_that_loads(tmp_path: Path, how: str) -> None:
    layout = _layout(tmp_path, env_steps=100_000_000)
    proc = _start(layout)
    try:
        _wait_for(lambda: len(read_metrics(layout.metrics_file)) >= 2, 120, "2 iterations")
        if how == "cancel":
            layout.cancel_file.touch()
        else:
            proc.send_signal(signal.SIGTERM)
    finally:
        rc, out = _finish(proc)
    assert rc == 0, out
    progress = read_progress(layout.progress_file)
    assert progress.phase == "stopped" and progress.error is None, out
    newest = latest_checkpoint(layout.checkpoints_dir)
    assert newest is not None and progress.checkpoint == newest.name
    _, meta = load_checkpoint(newest)
    assert meta.iteration == progress.iteration >= 2
    assert not layout.evaluation_dir.exists() and not layout.report_files()


def test_a_failure_at_run_time_is_reported_with_exit_code_1(tmp_path: Path) -> None:
    """The run directory holds a damaged checkpoint to resume from: the job validated at
    submission, and fails when its trainer starts."""
    layout = _layout(tmp_path, env_steps=1024)
    damaged = layout.checkpoints_dir / "ckpt-000000000512"
    damaged.mkdir(parents=True)
    (damaged / "manifest.json").write_text('{"policy.safetensors": "0"}')
    rc, out = _finish(_start(layout))
    assert rc == 1, out
    progress = read_progress(layout.progress_file)
    assert progress.phase == "failed", out
    assert "policy.safetensors: missing" in progress.error and "\n" not in progress.error
    assert "Traceback" in progress.traceback and "CheckpointError" in progress.traceback
    assert "failed: " in layout.log_file.read_text()


SEARCH_THEN_PPO = """name: reflex
ppo: {batch_env_steps: 60, minibatch_size: 30, epochs: 1}
workers: {num_workers: 0, envs_per_worker: 2, fragment_length: 30}
checkpoint: {every_iters: 1}
stages:
  - scene: reflex-walk-3d
    scene_set: {episode_s: 0.3}
    env_steps: 1000000
    optimize: {population: 4, generations: 2, episodes: 1}
  - scene: reflex-walk-3d
    scene_set: {episode_s: 0.3}
    env_steps: 60
"""


def test_a_cma_es_stage_then_ppo_runs_as_a_job(tmp_path: Path) -> None:
    """A job of a CMA-ES stage followed by a PPO stage runs through the entry like any other:
    its generations and its PPO iteration in metrics.jsonl, the final checkpoint evaluated
    with the tuned controller."""
    layout = JobLayout(tmp_path, "j-0123456789ac")
    write_job_files(layout, prepare_submission(SEARCH_THEN_PPO))
    rc, out = _finish(_start(layout, "--no-video"))
    assert rc == 0, out
    assert read_progress(layout.progress_file).phase == "finished", out
    rows = read_metrics(layout.metrics_file)
    assert [r.get("cmaes_generation") for r in rows] == [1, 2, None]
    assert [r["stage"] for r in rows] == [0, 0, 1]
    _, meta = load_checkpoint(latest_checkpoint(layout.checkpoints_dir))
    assert set(meta.scene["action"]["parameters"]) >= {"trunk.lean", "pose.ankle"}
    assert list(layout.reports_dir.glob("evaluate-*.json")), out
