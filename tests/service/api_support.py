"""Helpers of the REST API tests: a real uvicorn on loopback in a thread, raw HTTP requests
(paths sent byte for byte, no client normalising ``../``), and a job with artifacts on disk."""

from __future__ import annotations

import http.client
import json
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import uvicorn
from fastapi import FastAPI
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore

ALICE, BOB = "tok-alice-0123456789", "tok-bob-9876543210"
TOKENS = f"alice:{ALICE},bob:{BOB}"
SECRET = "SECRET-CONTENT-7f3a"
"""written into files outside any artifact listing: never in a response"""
CHECKPOINT = "ckpt-000000000256"


def auth(token: str = ALICE) -> dict[str, str]:
    """The Authorization header for ``token``."""
    return {"Authorization": f"Bearer {token}"}


@contextmanager
def serve(app: FastAPI) -> Iterator[int]:
    """``app`` on a real uvicorn at 127.0.0.1 (a free port, yielded) until the block ends."""
    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning", lifespan="on")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="uvicorn-test", daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started:
        assert thread.is_alive() and time.monotonic() < deadline, "uvicorn did not start"
        time.sleep(0.05)
    port = server.servers[0].sockets[0].getsockname()[1]
    try:
        yield port
    finally:
        server.should_exit = True
        thread.join(30)


def raw_get(port: int, path: str, token: str = ALICE) -> tuple[int, dict[str, str], bytes]:
    """GET ``path`` exactly as given (no normalising): status, headers, body."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        conn.putrequest("GET", path, skip_accept_encoding=True)
        conn.putheader("Authorization", f"Bearer {token}")
        conn.endheaders()
        response = conn.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        conn.close()


def raw_request(
    port: int,
    method: str,
    path: str,
    headers: dict[str, str] | None = None,
    body: bytes | None = None,
) -> tuple[int, dict[str, str], bytes]:
    """``method path`` exactly as given, with ``headers`` (``Host: 127.0.0.1`` unless they
    name another) and ``body``: status, headers (names lower-cased), body."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        for name, value in ({"Host": "127.0.0.1"} | (headers or {})).items():
            conn.putheader(name, value)
        if body is not None:
            conn.putheader("Content-Length", str(len(body)))
        conn.endheaders(body)
        response = conn.getresponse()
        found = {name.lower(): value for name, value in response.getheaders()}
        return response.status, found, response.read()
    finally:
        conn.close()


def seed_job(store: JobStore, settings: ServiceSettings, owner: str = "alice") -> JobRecord:
    """A job of ``owner`` in the store with files on disk: a checkpoint, two recordings, a
    report, a log, metrics; and secrets beside them that no listing names."""
    record = store.create(owner, "seeded", {"name": "seeded", "stages": []})
    layout = JobLayout(settings.artifacts, record.id)
    ckpt = layout.checkpoints_dir / CHECKPOINT
    ckpt.mkdir(parents=True)
    (ckpt / "policy.safetensors").write_bytes(bytes(range(256)) * 64)
    (ckpt / "meta.json").write_text(json.dumps({"env_steps": 256}))
    (ckpt / "manifest.json").write_text(json.dumps({"policy.safetensors": "0" * 64}))
    layout.recordings_dir.mkdir(parents=True)
    (layout.recordings_dir / "iter-000002.mcap").write_bytes(b"\x89MCAP0\r\n" + b"m" * 1000)
    layout.evaluation_dir.mkdir(parents=True)
    (layout.evaluation_dir / f"{CHECKPOINT}.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" * 50)
    layout.reports_dir.mkdir(parents=True)
    (layout.reports_dir / f"evaluate-{CHECKPOINT}.json").write_text(json.dumps({"return": 1.5}))
    layout.log_file.write_text("starting\nitération 1\n")
    lines = [json.dumps({"iteration": i, "env_steps": 256 * i, "return": float(i)}) for i in (1, 2)]
    layout.metrics_file.write_text("\n".join(lines) + '\n{"iteration": 3, "ret')
    layout.job_file.write_text(f"name: seeded  # {SECRET}\n")
    (layout.run_dir / "secret.txt").write_text(SECRET)
    (ckpt.parent / "secret.mcap").mkdir()  # not a checkpoint name, not a file
    Path(settings.artifacts, "secret.txt").write_text(SECRET)
    return record
