"""The REST service under load: requests/s of ``GET /v1/jobs/{id}`` and how old a job's
iteration is when the API first shows it, with 4 jobs running. Loopback only.

Usage: python bench/service.py [--seconds 10] [--requests 5000] [--clients 1 4]
                               [--poll-interval 1.0] [--out bench/results/service]

A real ``gaitforge serve`` (uvicorn, a local Ray head, SQLite) on a free loopback port with a
temporary home, ``max_running_jobs`` 4; four tiny in-process jobs (``elbow-reach``, 256 env
steps per iteration, a budget far beyond the measurement) are submitted and waited for until
each has shown an iteration. Then, one after the other:

* freshness: for ``--seconds``, every job's status is read every 50 ms by one client; the
  first answer showing a new iteration carries ``progress_age_s``, the time since the
  trainer wrote that iteration's progress.json (server clock, same machine): that is the
  iteration-to-API latency (it overstates by at most one round of reads: 50 ms of sleep
  and the four requests). The runner copies progress into the database every
  ``--poll-interval`` s, the main term.
* throughput: for each count in ``--clients``, that many threads (one keep-alive
  connection each) read the four jobs' statuses in turn for ``--seconds`` or ``--requests``
  answers in all, whichever comes first; requests/s and latency percentiles.

The jobs are cancelled, the service and its Ray head stopped and the home removed at the
end, also on failure. Prints a table; writes ``service.json`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
from gaitforge.service.client.round_trip import free_port, start_service, stop_service
from rich.console import Console
from rich.table import Table

console = Console()
JOBS = 4
READ_EVERY_S = 0.05
WARM_LIMIT_S = 300.0


def tiny_job(i: int) -> dict:
    """An in-process job that iterates about once a second and outlasts the bench."""
    return {
        "name": f"bench-{i}",
        "seed": i,
        "ppo": {"batch_env_steps": 256, "minibatch_size": 128, "epochs": 1},
        "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 128},
        "checkpoint": {"every_iters": 100000, "keep_last": 1},
        "stages": [{"scene": "elbow-reach", "env_steps": 100_000_000}],
    }


def wait_running(http: httpx.Client, ids: list[str]) -> None:
    """Until every job runs and shows an iteration (``WARM_LIMIT_S`` at most)."""
    deadline = time.monotonic() + WARM_LIMIT_S
    while time.monotonic() < deadline:
        found = [http.get(f"/v1/jobs/{i}").json() for i in ids]
        if any(s["state"] in ("failed", "cancelled", "succeeded") for s in found):
            raise RuntimeError(f"a bench job ended: {[(s['id'], s['error']) for s in found]}")
        if all(s["state"] == "running" and (s.get("iteration") or 0) >= 1 for s in found):
            return
        time.sleep(1.0)
    raise RuntimeError(f"the jobs did not all run within {WARM_LIMIT_S:.0f} s")


def freshness(http: httpx.Client, ids: list[str], seconds: float) -> dict:
    """Ages (s) of each newly seen iteration's progress when the API first showed it."""
    last = {i: http.get(f"/v1/jobs/{i}").json().get("iteration") for i in ids}
    ages: list[float] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for job_id in ids:
            status = http.get(f"/v1/jobs/{job_id}").json()
            if status.get("iteration") != last[job_id] and status.get("progress_age_s") is not None:
                ages.append(status["progress_age_s"])
                last[job_id] = status.get("iteration")
        time.sleep(READ_EVERY_S)
    return summary(ages, "iterations seen")


def throughput(
    server: str, token: str, ids: list[str], clients: int, seconds: float, limit: int
) -> dict:
    """``clients`` threads reading statuses for ``seconds`` or ``limit`` answers."""
    latencies: list[list[float]] = [[] for _ in range(clients)]
    errors = [0] * clients
    count = [0]
    lock = threading.Lock()
    stop_at = time.monotonic() + seconds

    def reader(k: int) -> None:
        with httpx.Client(base_url=server, headers={"Authorization": f"Bearer {token}"}) as c:
            n = 0
            while time.monotonic() < stop_at:
                with lock:
                    if count[0] >= limit:
                        return
                    count[0] += 1
                t0 = time.perf_counter()
                ok = c.get(f"/v1/jobs/{ids[(k + n) % len(ids)]}").status_code == 200
                latencies[k].append(time.perf_counter() - t0)
                errors[k] += not ok
                n += 1

    threads = [threading.Thread(target=reader, args=(k,)) for k in range(clients)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.perf_counter() - t0
    flat = [x for per in latencies for x in per]
    result = summary(flat, "requests")
    result.update(
        clients=clients, seconds=elapsed, errors=sum(errors), requests_per_s=len(flat) / elapsed
    )
    return result


def summary(values: list[float], label: str) -> dict:
    """Count, median, p95 and max of ``values`` (s)."""
    if not values:
        return {label: 0}
    ranked = sorted(values)
    return {
        label: len(ranked),
        "median_s": statistics.median(ranked),
        "p95_s": ranked[min(len(ranked) - 1, int(0.95 * len(ranked)))],
        "max_s": ranked[-1],
    }


def render(results: dict) -> Table:
    table = Table(title=f"gaitforge serve, {JOBS} jobs running, {os.cpu_count()} CPUs, loopback")
    for column in ("measure", "clients", "count", "rate /s", "median ms", "p95 ms", "max ms"):
        table.add_column(column, justify="left" if column == "measure" else "right")
    fresh = results["freshness"]
    table.add_row(
        "iteration -> GET /v1/jobs/{id}", "1", str(fresh.get("iterations seen", 0)), "", *_ms(fresh)
    )
    for row in results["throughput"]:
        table.add_row(
            "GET /v1/jobs/{id}",
            str(row["clients"]),
            str(row.get("requests", 0)),
            f"{row['requests_per_s']:.0f}",
            *_ms(row),
        )
    return table


def _ms(row: dict) -> list[str]:
    return [f"{1000 * row[k]:.1f}" if k in row else "-" for k in ("median_s", "p95_s", "max_s")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="per measurement (max 60)")
    parser.add_argument("--requests", type=int, default=5000, help="per throughput row (max)")
    parser.add_argument("--clients", type=int, nargs="+", default=[1, 4])
    parser.add_argument("--poll-interval", type=float, default=1.0, help="the runner's, s")
    parser.add_argument("--out", type=Path, default=Path("bench/results/service"))
    args = parser.parse_args()
    seconds = min(args.seconds, 60.0)
    home = Path(tempfile.mkdtemp(prefix="gaitforge-bench-"))
    port = free_port()
    server = f"http://127.0.0.1:{port}"
    env = {
        **os.environ,
        "GAITFORGE_HOME": str(home),
        "GAITFORGE_PORT": str(port),
        "GAITFORGE_HOST": "127.0.0.1",
        "GAITFORGE_SERVER": server,
        "GAITFORGE_MAX_RUNNING_JOBS": str(JOBS),
        "GAITFORGE_MAX_JOBS_PER_OWNER": str(JOBS),
        "GAITFORGE_POLL_INTERVAL_S": str(args.poll_interval),
    }
    for name in ("GAITFORGE_TOKENS", "GAITFORGE_TOKENS_FILE", "GAITFORGE_RAY_ADDRESS"):
        env.pop(name, None)
    service, ids = None, []
    results: dict = {
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "python": platform.python_version(),
        },
        "jobs": JOBS,
        "poll_interval_s": args.poll_interval,
        "seconds": seconds,
    }
    try:
        service = start_service(env, home / "serve.log")
        token = (home / "token").read_text().strip()
        auth = {"Authorization": f"Bearer {token}"}
        with httpx.Client(base_url=server, headers=auth, timeout=30.0) as http:
            ids = [
                http.post("/v1/jobs", json=tiny_job(i)).raise_for_status().json()["id"]
                for i in range(JOBS)
            ]
            console.print(f"jobs {ids}: waiting until each runs an iteration")
            wait_running(http, ids)
            console.print(f"freshness: reading statuses every {READ_EVERY_S * 1000:.0f} ms")
            results["freshness"] = freshness(http, ids, seconds)
            results["throughput"] = []
            for clients in args.clients:
                console.print(f"throughput: {clients} client(s), {seconds:.0f} s")
                row = throughput(server, token, ids, clients, seconds, args.requests)
                results["throughput"].append(row)
            for job_id in ids:
                http.post(f"/v1/jobs/{job_id}/cancel")
    finally:
        if service is not None:
            stop_service(service)
        subprocess.run(
            [sys.executable, "-m", "gaitforge.service.cli", "serve", "--stop-ray"],
            env=env,
            check=False,
        )
        shutil.rmtree(home, ignore_errors=True)
    console.print(render(results))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "service.json").write_text(json.dumps(results, indent=1))
    console.print(f"written: {args.out / 'service.json'}")


if __name__ == "__main__":
    main()
