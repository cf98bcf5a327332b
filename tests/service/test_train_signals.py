"""SIGTERM and SIGINT stop ``gaitforge train`` cleanly: a real ``gaitforge train`` process
gets SIGTERM once it iterates, checkpoints its last update, exits 0 naming it, and a second
run (through typer's runner: no second process start-up) resumes from that checkpoint; so it
does when the whole process group gets it (as from GNU ``timeout``: the local Ray it started
runs in a group of its own, ``workers/ray_start.py``). Off a terminal it logs status lines.
The signal comes after the first iteration: any iteration's stop goes the same way."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.service.cli import app
from gaitforge.service.signals import SignalStop
from typer.testing import CliRunner

JOB_BATCH = "batch_env_steps: 256, minibatch_size: 128"
JOB = """name: tiny
ppo: {batch_env_steps: 256, minibatch_size: 128, epochs: 1}
workers: {num_workers: 0, envs_per_worker: 2, fragment_length: 64}
checkpoint: {every_iters: 100000}
stages:
  - scene: elbow-reach
    env_steps: 100000000
"""
STATUS = re.compile(
    r"INFO gaitforge\.service\.ops\.train: stage 0 elbow-reach: iteration (\d+), [\d,]+ env "
    r"steps \([\d,]+ in stage\), [\d,]+ steps/s; return -?[\d.]+, speed -?[\d.]+ m/s, "
    r"falls \d+ %"
)


def _train_args(job: Path, run_dir: Path, *args: str) -> list[str]:
    return [
        "train",
        str(job),
        "--run-dir",
        str(run_dir),
        "--no-tensorboard",
        "--log-every",
        "0",
        *args,
    ]


def _train(job: Path, run_dir: Path, *args: str, new_session: bool = False) -> subprocess.Popen:
    command = [sys.executable, "-m", "gaitforge.service.cli", *_train_args(job, run_dir, *args)]
    env = {**os.environ, "COLUMNS": "200", "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=new_session,
    )


def _lines(stream) -> queue.Queue:
    lines: queue.Queue = queue.Queue()

    def pump() -> None:
        for line in stream:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return lines


def _wait_for_iteration(lines: queue.Queue, n: int, timeout_s: float) -> list[str]:
    """stderr lines up to the status line of iteration ``n`` or later."""
    seen: list[str] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1.0)
        except queue.Empty:
            continue
        if line is None:
            break
        seen.append(line)
        match = STATUS.search(line)
        if match and int(match.group(1)) >= n:
            return seen
    pytest.fail(f"no status line for iteration {n}; stderr:\n{''.join(seen)}")


@pytest.mark.parametrize(
    "workers, to_group",
    [("0", False), ("1", False), ("1", True)],
    ids=["in-process", "ray", "ray-process-group"],
)
def test_sigterm_checkpoints_exits_0_and_the_run_resumes(
    tmp_path: Path, workers: str, to_group: bool
) -> None:
    job, run_dir = tmp_path / "job.yaml", tmp_path / "run"
    # to the group: batches of 32 fragments, so that the signal comes while most are still to
    # be made by an actor it kills (with 2, both are often back already)
    batch = "batch_env_steps: 4096, minibatch_size: 1024" if to_group else None
    job.write_text(JOB if batch is None else JOB.replace(JOB_BATCH, batch))
    proc = _train(job, run_dir, "--workers", workers, new_session=to_group)
    lines = _lines(proc.stderr)
    try:
        _wait_for_iteration(lines, 1, timeout_s=240)
        if to_group:  # the driver and the local Ray head it started, as GNU timeout does
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.send_signal(signal.SIGTERM)
        out = proc.stdout.read()
        rc = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = []
    while (line := lines.get(timeout=10)) is not None:
        err.append(line)
    assert rc == 0, out + "".join(err)
    assert "SIGTERM: stopping with a checkpoint of the last update" in "".join(err)
    assert "Traceback" not in "".join(err) and "SIGTERM received" not in "".join(err)
    found = re.search(r"SIGTERM: stopped after iteration (\d+) .*checkpoint: (\S+) ", out)
    assert found, out
    iteration, checkpoint = int(found.group(1)), Path(found.group(2))
    assert checkpoint == latest_checkpoint(run_dir / "checkpoints")
    _, meta = load_checkpoint(checkpoint)
    assert meta.iteration == iteration >= 1  # written at the stop, not periodically

    args = _train_args(job, run_dir, "--workers", "0", "--max-iterations", "1")
    again = CliRunner().invoke(app, args, env={"COLUMNS": "200"})
    assert again.exit_code == 0, again.output
    _, meta = load_checkpoint(latest_checkpoint(run_dir / "checkpoints"))
    assert meta.iteration == iteration + 1, "the second run went on from the stop's checkpoint"


def test_a_second_signal_stops_at_once() -> None:
    """The first signal asks to stop; the second raises KeyboardInterrupt; handlers are
    given back."""
    before = signal.getsignal(signal.SIGTERM)
    stops: list[int] = []
    with pytest.raises(KeyboardInterrupt), SignalStop() as signals:
        signals.on_stop(lambda: stops.append(1))
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)  # the handler runs in the main thread between bytecodes
        assert stops == [1] and signals.first is signal.SIGTERM
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    assert signal.getsignal(signal.SIGTERM) == before


def test_a_signal_before_there_is_anything_to_stop_is_remembered() -> None:
    with SignalStop() as signals:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
        stops: list[int] = []
        signals.on_stop(lambda: stops.append(1))
        assert stops == [1]
