"""End to end through a real uvicorn on loopback, a started runner and the session's Ray head:
submit a tiny job, follow its server-sent events to the end, then read its log and metrics
and download a checkpoint (whole and by Range, sha256 checked), a report and a recording."""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from collections.abc import Iterator

import httpx
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobStore

from tests.service.api_support import TOKENS, auth, serve
from tests.service.conftest import make_tiny_job


def sse_events(response: httpx.Response) -> Iterator[tuple[str, str]]:
    """(event, data) of each event of a ``text/event-stream`` response; comments dropped."""
    event, data = "message", []
    for line in response.iter_lines():
        if not line:
            if data:
                yield event, "\n".join(data)
            event, data = "message", []
        elif line.startswith(":"):
            continue
        else:
            field, _, value = line.partition(":")
            value = value.removeprefix(" ")
            if field == "event":
                event = value
            elif field == "data":
                data.append(value)


def test_submit_follow_and_download(
    service_settings: ServiceSettings, store: JobStore, ray_connection
) -> None:
    settings = service_settings.model_copy(update={"tokens": TOKENS})
    runner = JobRunner(settings, store, ray_connection, evaluate_episodes=1)
    runner.start()
    try:
        with serve(create_app(settings, runner)) as port:
            base = f"http://127.0.0.1:{port}"
            with httpx.Client(base_url=base, headers=auth(), timeout=30) as client:
                _round_trip(client)
    finally:
        runner.stop()


def _round_trip(client: httpx.Client) -> None:
    r = client.post("/v1/jobs", json=make_tiny_job(name="round-trip"))
    assert r.status_code == 201, r.text
    job_id = r.json()["id"]

    events: list[tuple[str, dict]] = []
    with client.stream("GET", f"/v1/jobs/{job_id}/events", timeout=300) as stream:
        assert stream.status_code == 200
        assert stream.headers["content-type"].startswith("text/event-stream")
        for event, data in sse_events(stream):
            events.append((event, json.loads(data)))
            if event == "end":
                break
    kinds = [e for e, _ in events]
    assert kinds[-1] == "end" and kinds.count("end") == 1 and "progress" in kinds
    final = events[-1][1]
    assert final["state"] == "succeeded", final.get("error")
    states = [d["state"] for e, d in events if e == "progress"]
    assert states[0] in ("queued", "running") and states[-1] == "succeeded"
    assert final["env_steps"] >= 1024 and final["latest_checkpoint"]
    status = client.get(f"/v1/jobs/{job_id}").json()
    assert status["state"] == "succeeded" and status["actions"] == [] and status["finished_at"]

    log, offset = "", 0
    while True:
        chunk = client.get(f"/v1/jobs/{job_id}/logs", params={"offset": offset}).json()
        log, offset = log + chunk["text"], chunk["next_offset"]
        if chunk["eof"]:
            break
    assert log and offset == len(log.encode())
    points = client.get(f"/v1/jobs/{job_id}/metrics").json()["points"]
    assert len(points) >= 4 and points[-1]["iteration"] == len(points)

    checkpoints = client.get(f"/v1/jobs/{job_id}/checkpoints").json()["items"]
    assert final["latest_checkpoint"] in [c["name"] for c in checkpoints]
    url = f"/v1/jobs/{job_id}/checkpoints/{final['latest_checkpoint']}"
    whole = client.get(url)
    assert whole.status_code == 200 and whole.headers["accept-ranges"] == "bytes"
    digest = whole.headers["x-content-sha256"]
    assert hashlib.sha256(whole.content).hexdigest() == digest
    half = len(whole.content) // 2
    head = client.get(url, headers={"Range": f"bytes=0-{half - 1}"})
    tail = client.get(url, headers={"Range": f"bytes={half}-"})
    assert head.status_code == tail.status_code == 206
    assert hashlib.sha256(head.content + tail.content).hexdigest() == digest
    names = zipfile.ZipFile(io.BytesIO(whole.content)).namelist()
    assert any(n.endswith("/policy.safetensors") for n in names)
    assert client.get(url).headers["x-content-sha256"] == digest  # built once, same zip

    reports = client.get(f"/v1/jobs/{job_id}/reports").json()["items"]
    assert reports, "no evaluation report"
    report = client.get(reports[0]["href"])
    assert report.status_code == 200 and isinstance(report.json(), dict)
    recordings = client.get(f"/v1/jobs/{job_id}/recordings").json()["items"]
    by_type = {r["media_type"]: r for r in recordings}
    assert {"application/x-mcap", "video/mp4"} <= set(by_type), recordings
    mcap = client.get(by_type["application/x-mcap"]["href"])
    assert mcap.content.startswith(b"\x89MCAP")
    assert hashlib.sha256(mcap.content).hexdigest() == mcap.headers["x-content-sha256"]
