"""The service's round trip, as ``make run`` does it: start ``gaitforge serve`` on a fresh port
with its state in ``OUT/service``, submit a job (scaled down), follow it live, download its
final checkpoint, recordings and report, evaluate the checkpoint with an MCAP recording and a
video, and stop the service and its local Ray head, even when a step fails.

    python -m gaitforge.service.client.round_trip [--job examples/gait2d-curriculum.yaml]
        [--budget-scale 0.001] [--out runs/make-run] [--episodes 5]

Every step is a ``gaitforge`` command, echoed as a user would type it.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
from gaitforge.service.console import err, out

START_LIMIT_S = 180.0
STOP_LIMIT_S = 30.0


def gaitforge(args: list[str], env: dict[str, str], capture: bool = False) -> str:
    """Run ``gaitforge ARGS`` (echoed), stderr to the terminal; its stdout if ``capture``.

    Raises:
        RuntimeError: the command failed (its exit status).
    """
    err.print(f"[bold]$ gaitforge {shlex.join(args)}[/bold]", soft_wrap=True, highlight=False)
    command = [sys.executable, "-m", "gaitforge.service.cli", *args]
    done = subprocess.run(
        command, env=env, check=False, text=True, stdout=subprocess.PIPE if capture else None
    )
    if done.returncode != 0:
        if done.stdout:
            err.print(done.stdout.rstrip(), soft_wrap=True, highlight=False, markup=False)
        raise RuntimeError(f"gaitforge {args[0]} exited with status {done.returncode}")
    return done.stdout or ""


def free_port() -> int:
    """A TCP port free on loopback now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_service(env: dict[str, str], log: Path) -> subprocess.Popen:
    """``gaitforge serve`` in the background (output in ``log``), once /healthz answers.

    Raises:
        RuntimeError: it exited, or did not answer within ``START_LIMIT_S``.
    """
    server = env["GAITFORGE_SERVER"]
    err.print(f"[bold]$ gaitforge serve &[/bold]  (log: {log})", highlight=False)
    with log.open("ab") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "gaitforge.service.cli", "serve"],
            env=env,
            stdout=sink,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    deadline = time.monotonic() + START_LIMIT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            tail = log.read_text(errors="replace").splitlines()[-15:]
            raise RuntimeError("gaitforge serve exited:\n" + "\n".join(tail))
        try:
            if httpx.get(f"{server}/healthz", timeout=2.0).status_code == 200:
                return process
        except httpx.TransportError:
            pass
        time.sleep(0.5)
    stop_service(process)
    raise RuntimeError(f"gaitforge serve did not answer at {server} in {START_LIMIT_S:.0f} s")


def stop_service(process: subprocess.Popen) -> None:
    """SIGTERM (uvicorn shuts down cleanly), SIGKILL after ``STOP_LIMIT_S``."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(STOP_LIMIT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def round_trip(job: Path, budget_scale: float, out_dir: Path, episodes: int) -> dict[str, Path]:
    """The whole trip; returns where its results are. The service and its Ray head are
    stopped whatever happens."""
    home, downloads = out_dir / "service", out_dir / "download"
    home.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(downloads, ignore_errors=True)
    port = free_port()
    env = {
        **os.environ,
        "GAITFORGE_HOME": str(home),
        "GAITFORGE_PORT": str(port),
        "GAITFORGE_SERVER": f"http://127.0.0.1:{port}",
    }
    for name in ("GAITFORGE_TOKEN", "GAITFORGE_TOKEN_FILE", "GAITFORGE_TOKENS"):
        env.pop(name, None)  # the service's generated token in home/token
    service = None
    try:
        service = start_service(env, home / "serve.log")
        submitted = gaitforge(
            ["submit", str(job), "--budget-scale", str(budget_scale), "--follow", "--json"],
            env,
            capture=True,
        )
        job_id = json.loads(submitted)["id"]
        fetched = gaitforge(
            [
                "download",
                job_id,
                "--checkpoint",
                "latest",
                "--recording",
                "latest",
                "--report",
                "latest",
                "--out",
                str(downloads),
                "--json",
            ],
            env,
            capture=True,
        )
        files = json.loads(fetched)["files"]
        checkpoint = Path(next(f["path"] for f in files if f["kind"] == "checkpoints"))
        evaluation = out_dir / "evaluate"
        gaitforge(
            [
                "evaluate",
                str(checkpoint),
                "--episodes",
                str(episodes),
                "--sweep",
                "--record",
                f"{evaluation}.mcap",
                "--video",
                f"{evaluation}.mp4",
                "--json-out",
                f"{evaluation}.json",
            ],
            env,
        )
    finally:
        if service is not None:
            err.print("[bold]stopping the service[/bold]", highlight=False)
            stop_service(service)
        try:
            gaitforge(["serve", "--stop-ray"], env)
        except RuntimeError as exc:
            err.print(f"[yellow]warning:[/yellow] {exc}", highlight=False)
    found = {"service state (database, job files, token)": home, "service log": home / "serve.log"}
    found[f"job {job_id}"] = home / "artifacts" / "jobs" / job_id
    for item in files:
        found[f"downloaded {item['kind']} {item['name']}"] = Path(item["path"])
    for suffix in ("mcap", "mp4", "json"):
        found[f"evaluation {suffix}"] = Path(f"{evaluation}.{suffix}")
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--job", type=Path, default=Path("examples/gait2d-curriculum.yaml"))
    parser.add_argument("--budget-scale", type=float, default=0.001)
    parser.add_argument("--out", type=Path, default=Path("runs/make-run"))
    parser.add_argument("--episodes", type=int, default=5)
    args = parser.parse_args(argv)
    try:
        found = round_trip(args.job, args.budget_scale, args.out, args.episodes)
    except (RuntimeError, OSError, ValueError, KeyError, StopIteration) as exc:
        err.print(f"[red]error:[/red] round trip failed: {exc}", soft_wrap=True, highlight=False)
        return 1
    out.print("\n[bold]where everything is[/bold]")
    for label, path in found.items():
        out.print(f"  {label}: {path}", soft_wrap=True, highlight=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
