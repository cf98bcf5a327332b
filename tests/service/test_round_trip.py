"""The round trip through a real ``gaitforge serve`` (uvicorn on loopback, the session's Ray
head, SQLite in a temporary home) driven by the CLI client: submit (a scene file sent
inline), follow to success, list, status, logs, download with sha256 checks, load the
checkpoint; errors as one line; a job that keeps running while the service is killed with
SIGKILL and started again; no listening beyond loopback without tokens."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
import yaml
from gaitforge.learner.checkpoint import load_checkpoint
from gaitforge.service.cli import app
from gaitforge.service.client.round_trip import free_port, start_service
from gaitforge.service.jobs.ray_cluster import STATE_FILE, TOKEN_FILE, RayConnection
from gaitforge.workers.scenes import scene_fields
from typer.testing import CliRunner

runner = CliRunner()
CLI = [sys.executable, "-m", "gaitforge.service.cli"]


class Service:
    """A ``gaitforge serve`` process on ``home`` and a free loopback port."""

    def __init__(self, home: Path, port: int | None = None) -> None:
        self.home = home
        self.server = f"http://127.0.0.1:{port or free_port()}"
        self.env = {
            **os.environ,
            "GAITFORGE_HOME": str(home),
            "GAITFORGE_SERVER": self.server,
            "GAITFORGE_PORT": self.server.rsplit(":", 1)[1],
            "GAITFORGE_POLL_INTERVAL_S": "0.2",
            "COLUMNS": "250",
        }
        for name in ("GAITFORGE_TOKEN", "GAITFORGE_TOKEN_FILE", "GAITFORGE_TOKENS"):
            self.env.pop(name, None)
        self.process: subprocess.Popen | None = None

    def start(self) -> Service:
        self.process = start_service(self.env, self.home / "serve.log")
        return self

    def kill(self) -> None:
        """SIGKILL, as a crash would."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGKILL)
            self.process.wait()

    def cli(self, *args: str) -> tuple[int, str]:
        """``gaitforge ARGS`` through typer's runner against this service."""
        result = runner.invoke(app, list(args), env=self.env)
        return result.exit_code, result.output

    def status(self, job_id: str) -> dict:
        code, output = self.cli("status", job_id, "--json")
        assert code == 0, output
        return json.loads(output)


class Services:
    """The module's ``gaitforge serve`` processes, one after another on one home (re-attached
    to the session's Ray head, which the session's fixture stops)."""

    def __init__(self, home: Path) -> None:
        self.home = home
        self.started: list[Service] = []

    def running(self) -> Service:
        """The newest service if it still runs (the tests that only use a service share it:
        each start-up imports torch and Ray, seconds), else a new one."""
        newest = self.started[-1] if self.started else None
        if newest is not None and newest.process is not None and newest.process.poll() is None:
            return newest
        return self.start()

    def start(self, port: int | None = None) -> Service:
        """A new service (on ``port``: the port of one that was killed)."""
        self.started.append(Service(self.home, port).start())
        return self.started[-1]


@pytest.fixture(scope="module")
def services(
    tmp_path_factory: pytest.TempPathFactory, ray_connection: RayConnection, ray_home: Path
) -> Iterator[Services]:
    """The module's services, on a home of their own; each is killed at the end."""
    home = tmp_path_factory.mktemp("round-trip") / "home"
    home.mkdir()
    for name in (STATE_FILE, TOKEN_FILE):
        shutil.copy2(ray_home / name, home / name)
    started = Services(home)
    yield started
    for each in started.started:
        each.kill()


def test_submit_follow_download_and_load(
    services: Services, tiny_job: Callable[..., dict], tmp_path: Path
) -> None:
    svc = services.running()
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "my-stand.yaml").write_text(
        yaml.safe_dump({**scene_fields("stand-2d"), "name": "my-stand"})
    )
    spec = tiny_job(name="round-trip", env_steps=1024)
    spec["stages"][0]["scene"] = "scenes/my-stand.yaml"
    (tmp_path / "job.yaml").write_text(yaml.safe_dump(spec))
    code, output = svc.cli("submit", str(tmp_path / "job.yaml"), "--follow", "--json")
    assert code == 0, output
    final = json.loads(output[output.index("{") :])
    job_id = final["id"]
    assert final["state"] == "succeeded" and final["stage"]["name"] == "my-stand", final
    code, output = svc.cli("jobs", "--json")
    assert code == 0 and job_id in [j["id"] for j in json.loads(output)["items"]], output
    code, output = svc.cli("status", job_id)
    assert code == 0 and "succeeded" in output and "my-stand" in output, output
    code, output = svc.cli("logs", job_id, "--follow")
    assert code == 0 and output.strip(), "the trainer's log reads to its end"
    out = tmp_path / "download"
    code, output = svc.cli(
        "download",
        job_id,
        "--checkpoint",
        "latest",
        "--recording",
        "latest",
        "--report",
        "latest",
        "--out",
        str(out),
        "--json",
    )
    assert code == 0, output
    files = json.loads(output)["files"]
    kinds = {f["kind"] for f in files}
    assert kinds == {"checkpoints", "recordings", "reports"}, files
    checkpoint = Path(next(f["path"] for f in files if f["kind"] == "checkpoints"))
    assert checkpoint == out / final["latest_checkpoint"]
    _, meta = load_checkpoint(checkpoint)
    assert meta.env_steps >= 1024
    assert {Path(f["name"]).suffix for f in files if f["kind"] == "recordings"} >= {".mcap"}
    for item in files:
        assert Path(item["path"]).exists() and len(item["sha256"]) == 64
    _errors_are_one_line(svc, tiny_job, tmp_path)


def _errors_are_one_line(svc: Service, tiny_job: Callable[..., dict], tmp_path: Path) -> None:
    """A spec the service refuses, a bad token and an unknown job: one line each, exit 1."""
    bad = tiny_job()
    bad["workers"]["ray_address"] = "auto"
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    for args, expected in [
        (("submit", str(tmp_path / "bad.yaml")), "422 Unprocessable"),
        (("jobs", "--token", "wrong"), "401 Unauthorized"),
        (("status", "j-000000000000"), "404 Not Found"),
        (("download", "j-000000000000", "--out", str(tmp_path / "none")), "404 Not Found"),
    ]:
        code, output = svc.cli(*args)
        lines = output.strip().splitlines()
        assert code == 1 and len(lines) == 1 and lines[0].startswith("error:"), output
        assert expected in lines[0], output
    assert "workers.ray_address" in svc.cli("submit", str(tmp_path / "bad.yaml"))[1]


def test_a_job_keeps_running_across_a_killed_service(
    services: Services, tiny_job: Callable[..., dict], tmp_path: Path
) -> None:
    """The job outlives its service, and a follower (``status --follow``) outlives the
    outage: the second service starts only once the follower has found the first gone, so
    the outage is seen however slowly the follower is scheduled. The service is killed at
    the first of 12 iterations: the job may end while the service is away (the second one
    then finds it ended, attempt 1), and the test waits for no more training than that."""
    first = services.running()
    headers = {"Authorization": f"Bearer {(first.home / 'token').read_text().strip()}"}
    spec = tiny_job(name="outlives", env_steps=256 * 12, every_iters=4)
    job = httpx.post(f"{first.server}/v1/jobs", json=spec, headers=headers).raise_for_status()
    job_id = job.json()["id"]
    follower_log = tmp_path / "follower.err"
    with follower_log.open("w") as errors_out:
        follower = subprocess.Popen(
            [*CLI, "status", job_id, "--follow", "--json"],
            env=first.env,
            text=True,
            stdout=subprocess.PIPE,
            stderr=errors_out,
        )
    try:
        before = _wait(first, job_id, lambda s: (s.get("iteration") or 0) >= 1, 90)
        first.kill()
        deadline = time.monotonic() + 60
        while "unreachable; retrying" not in follower_log.read_text():
            assert follower.poll() is None, follower_log.read_text()
            assert time.monotonic() < deadline, "the follower never found the service gone"
            time.sleep(0.2)
        second = services.start(int(first.server.rsplit(":", 1)[1]))  # same home, port, head
        after = _wait(
            second, job_id, lambda s: (s.get("iteration") or 0) > before["iteration"], 120
        )
        assert after["state"] in ("running", "succeeded"), after
        output, _ = follower.communicate(timeout=120)
    finally:
        follower.kill()
    errors = follower_log.read_text()
    assert follower.returncode == 0, errors
    final = json.loads(output)
    assert final["state"] == "succeeded" and final["attempt"] == 1, final


def test_serve_refuses_other_hosts_without_tokens(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("GAITFORGE_")}
    done = subprocess.run(
        [*CLI, "serve", "--host", "0.0.0.0", "--home", str(tmp_path)],
        env=env,
        text=True,
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--host 0.0.0.0" in lines[0] and "TOKENS" in lines[0], done.stderr
    assert not (tmp_path / "gaitforge.db").exists(), "refused before anything started"


def _wait(svc: Service, job_id: str, done: Callable[[dict], bool], timeout_s: float) -> dict:
    """Poll the job's status through the CLI until ``done``; fail naming its last state."""
    deadline = time.monotonic() + timeout_s
    while True:
        status = svc.status(job_id)
        if done(status):
            return status
        assert status["state"] not in ("failed", "cancelled"), status
        if time.monotonic() > deadline:
            pytest.fail(f"{job_id}: {status['state']} at iteration {status.get('iteration')}")
        time.sleep(0.2)
