"""REST API behaviour on a real store and a real (not started) runner: submit as JSON and
YAML (201), bad specs (422 naming the field), other media (415), the per-owner limit (429),
paging and the state filter, logs by offset, metrics since an iteration, cancel and resume
(409 where the state does not allow it), status from progress, scenes, the OpenAPI document."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import timedelta

import pytest
import yaml
from fastapi.testclient import TestClient
from gaitforge.service.api import create_app
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.progress import JobProgress, now
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobStore, open_store
from jsonschema import Draft202012Validator

from tests.service.api_support import BOB, TOKENS, auth, seed_job, serve
from tests.service.conftest import make_tiny_job

PROBLEM = "application/problem+json"


@dataclass
class Api:
    client: TestClient
    settings: ServiceSettings
    store: JobStore


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[Api]:
    """Jobs stay queued: the runner is real but not started. Two jobs per owner."""
    settings = ServiceSettings(
        home=tmp_path_factory.mktemp("api-jobs"), tokens=TOKENS, max_jobs_per_owner=2
    )
    store = open_store(settings.db_url)
    with TestClient(create_app(settings, JobRunner(settings, store, ray_connection))) as client:
        yield Api(client, settings, store)
    store.close()


def _problem(r, status: int) -> dict:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    body = r.json()
    assert body["status"] == status and body["title"] and body["instance"]
    return body


def test_submit_json_and_yaml_then_the_limit(api: Api) -> None:
    spec = make_tiny_job(name="as-json")
    r = api.client.post("/v1/jobs", json=spec, headers=auth(BOB))
    assert r.status_code == 201, r.text
    job = r.json()
    assert r.headers["location"] == f"/v1/jobs/{job['id']}"
    assert job["state"] == "queued" and job["name"] == "as-json" and job["attempt"] == 0
    assert [a["name"] for a in job["actions"]] == ["cancel"]
    text = yaml.safe_dump(make_tiny_job(name="as-yaml"))
    for media in ("application/yaml", "text/yaml"):
        headers = {**auth(BOB), "Content-Type": media}
        r = api.client.post("/v1/jobs", content=text, headers=headers)
        if media == "application/yaml":
            assert r.status_code == 201 and r.json()["name"] == "as-yaml", r.text
        else:  # bob has 2 queued jobs: the limit
            body = _problem(r, 429)
            assert "bob" in body["detail"] and body["type"].endswith("job-limit")
    listed = api.client.get("/v1/jobs", params={"state": "queued"}, headers=auth(BOB)).json()
    assert listed["total"] == 2 and {j["name"] for j in listed["items"]} == {"as-json", "as-yaml"}
    page = api.client.get("/v1/jobs", params={"limit": 1, "offset": 1}, headers=auth(BOB)).json()
    assert page["total"] == 2 and len(page["items"]) == 1 and page["limit"] == 1
    assert api.client.get("/v1/jobs?state=running", headers=auth(BOB)).json()["total"] == 0
    _problem(api.client.get("/v1/jobs?state=bogus", headers=auth(BOB)), 422)
    typo = _problem(api.client.get("/v1/jobs?stat=queued", headers=auth(BOB)), 422)
    assert typo["errors"][0]["field"] == "stat" and "state" in typo["errors"][0]["message"]
    # a queued job cancels at once; it resumes (queued again), and only once
    cancelled = api.client.post(f"/v1/jobs/{job['id']}/cancel", headers=auth(BOB)).json()
    assert cancelled["state"] == "cancelled" and cancelled["actions"][0]["name"] == "resume"
    resumed = api.client.post(f"/v1/jobs/{job['id']}/resume", headers=auth(BOB))
    assert resumed.status_code == 200 and resumed.json()["state"] == "queued"
    body = _problem(api.client.post(f"/v1/jobs/{job['id']}/resume", headers=auth(BOB)), 409)
    assert "queued" in body["detail"]


@pytest.mark.parametrize(
    ("body", "media", "field"),
    [
        (
            {**make_tiny_job(), "stages": [{"scene": "walk-9d", "env_steps": 10}]},
            None,
            "stages.0.scene",
        ),
        (
            {**make_tiny_job(), "stages": [{"scene": "../../etc/x.yaml", "env_steps": 10}]},
            None,
            "stages.0.scene",
        ),
        ({**make_tiny_job(), "entrypoint": "rm -rf /"}, None, "entrypoint"),
        (
            {**make_tiny_job(), "workers": {"ray_address": "ray://evil:10001"}},
            None,
            "workers.ray_address",
        ),
        ({**make_tiny_job(), "ppo": {"lr": -1}}, None, "ppo.lr"),
        ("[1, 2]", "application/json", "body"),
        ("{not json", "application/json", "body"),
        ("a: &x [1]\nb: *x\n", "application/yaml", "body"),
        ("name: [unclosed", "text/yaml", "body"),
    ],
)
def test_bad_specs_are_422_naming_the_field(api: Api, body, media: str | None, field) -> None:
    if media is None:
        r = api.client.post("/v1/jobs", json=body, headers=auth())
    else:
        r = api.client.post("/v1/jobs", content=body, headers={**auth(), "Content-Type": media})
    problem = _problem(r, 422)
    assert field in [e["field"] for e in problem["errors"]], problem
    assert all(e["message"] for e in problem["errors"])


def test_other_media_types_are_415(api: Api) -> None:
    r = api.client.post("/v1/jobs", content=b"x", headers={**auth(), "Content-Type": "text/csv"})
    assert "application/yaml" in _problem(r, 415)["detail"]


def test_status_logs_and_metrics_from_the_job_files(api: Api) -> None:
    job = seed_job(api.store, api.settings)
    layout = JobLayout(api.settings.artifacts, job.id)
    progress = JobProgress(
        phase="training",
        pid=1,
        host="h",
        updated_at=now() - timedelta(seconds=3),
        iteration=2,
        env_steps=512,
        steps_per_s=900.0,
        checkpoint="ckpt-000000000256",
        metrics={
            "return": 1.5,
            "survival": 0.5,
            "reward_terms": {"alive": 1.0},
            "health": {"nan_state": 2},
        },
    )
    api.store.update(job.id, state="running", attempt=1, progress_json=progress.model_dump_json())
    base = f"/v1/jobs/{job.id}"
    status = api.client.get(base, headers=auth()).json()
    assert status["state"] == "running" and status["env_steps"] == 512
    assert status["health"] == {"nan_state": 2} and "health" not in status["metrics"]
    assert status["metrics"]["reward_terms"] == {"alive": 1.0}
    assert 3 <= status["progress_age_s"] < 60
    assert status["links"]["latest_checkpoint"] == f"{base}/checkpoints/ckpt-000000000256"

    metrics = api.client.get(f"{base}/metrics", headers=auth()).json()
    assert [p["iteration"] for p in metrics["points"]] == [1, 2]  # the half line skipped
    newer = api.client.get(f"{base}/metrics?since=1", headers=auth()).json()
    assert [p["iteration"] for p in newer["points"]] == [2] and newer["last_iteration"] == 2
    first = api.client.get(f"{base}/metrics?limit=1", headers=auth()).json()
    assert [p["iteration"] for p in first["points"]] == [1] and first["last_iteration"] == 1

    whole = "starting\nitération 1\n"  # "é" is 2 bytes: a limit of 12 splits it
    chunk = api.client.get(f"{base}/logs?offset=0&limit=12", headers=auth()).json()
    assert chunk["text"] == "starting\nit" and chunk["next_offset"] == 11 and not chunk["eof"]
    rest = api.client.get(f"{base}/logs?offset=11", headers=auth()).json()
    assert chunk["text"] + rest["text"] == whole and not rest["eof"]  # still running
    api.store.update(job.id, state="succeeded")
    end = api.client.get(f"{base}/logs?offset={rest['next_offset']}", headers=auth()).json()
    assert end["text"] == "" and end["eof"]
    assert _problem(api.client.post(f"{base}/cancel", headers=auth()), 409)
    layout.log_file.unlink()
    assert api.client.get(f"{base}/logs", headers=auth()).json()["eof"]


def test_checkpoint_zip_is_built_once_with_its_sha256(api: Api) -> None:
    import hashlib
    import io
    import zipfile

    job = seed_job(api.store, api.settings)
    url = f"/v1/jobs/{job.id}/checkpoints/ckpt-000000000256"
    first = api.client.get(url, headers=auth())
    assert first.status_code == 200 and first.headers["content-type"] == "application/zip"
    assert hashlib.sha256(first.content).hexdigest() == first.headers["x-content-sha256"]
    names = zipfile.ZipFile(io.BytesIO(first.content)).namelist()
    assert "ckpt-000000000256/policy.safetensors" in names
    part = api.client.get(url, headers={**auth(), "Range": "bytes=10-19"})
    assert part.status_code == 206 and part.content == first.content[10:20]
    assert part.headers["x-content-sha256"] == first.headers["x-content-sha256"]
    _problem(api.client.get(url, headers={**auth(), "Range": "bytes=999999-"}), 416)
    report = api.client.get(
        f"/v1/jobs/{job.id}/reports/evaluate-ckpt-000000000256.json", headers=auth()
    )
    assert report.json() == {"return": 1.5}


def test_scenes(api: Api) -> None:
    scenes = api.client.get("/v1/scenes", headers=auth()).json()
    assert "stand-2d" in [s["name"] for s in scenes]
    report = api.client.get("/v1/scenes/stand-2d", headers=auth()).json()
    assert report["scene"] == "stand-2d" and report["size"]["muscles"] > 0
    _problem(api.client.get("/v1/scenes/walk-9d", headers=auth()), 404)
    _problem(api.client.get("/v1/scenes/..%2Fcatalogue%2Fstand-2d.yaml", headers=auth()), 404)
    _problem(api.client.get("/v1/scenes/stand-2d?backend=bogus", headers=auth()), 422)


def test_composed_scenes_and_their_options(api: Api) -> None:
    """A scene is a base and options, with fields set as --set sets them."""
    options = api.client.get("/v1/scenes/options", headers=auth()).json()
    assert {"clock", "one-leg", "obstacles"} <= {o["name"] for o in options}
    url = "/v1/scenes/run-2d+clock+obstacles"
    report = api.client.get(url, params={"set": "obstacles.count=3"}, headers=auth()).json()
    assert report["scene"] == "run-2d+clock+obstacles" and report["obstacles"] == 3
    _problem(api.client.get("/v1/scenes/run-2d+wings", headers=auth()), 404)
    _problem(api.client.get("/v1/scenes/stand-2d+clock", headers=auth()), 404)
    bad = _problem(api.client.get(url, params={"set": "obstacles.cuont=3"}, headers=auth()), 422)
    assert "obstacles.cuont" in bad["detail"]


def test_openapi_documents_every_response(api: Api) -> None:
    doc = api.client.get("/openapi.json").json()
    assert api.client.get("/docs").status_code == 200
    schemas = doc["components"]["schemas"]
    assert "HTTPValidationError" not in schemas
    for name, schema in schemas.items():  # every schema has an example, and it is valid
        assert schema.get("examples"), name
        validator = Draft202012Validator({"$ref": f"#/components/schemas/{name}", **doc})
        for example in schema["examples"]:
            assert not list(validator.iter_errors(example)), (name, example)
    for path, operations in doc["paths"].items():
        for method, op in operations.items():
            codes = set(op["responses"])
            if path != "/healthz":
                assert {"401"} <= codes and op["security"] == [{"bearer": []}], (method, path)
            if "{job_id}" in path:
                assert {"404", "422"} <= codes, (method, path)
            for code, response in op["responses"].items():
                if code.startswith(("4", "5")):
                    assert list(response["content"]) == [PROBLEM], (method, path, code)
                    assert response["content"][PROBLEM]["example"]["status"] == int(code)
    post = doc["paths"]["/v1/jobs"]["post"]
    assert {"413", "415", "422", "429"} <= set(post["responses"])
    assert set(post["requestBody"]["content"]) >= {"application/json", "application/yaml"}
    example = post["requestBody"]["content"]["application/json"]["example"]
    assert not list(
        Draft202012Validator({"$ref": "#/components/schemas/Job", **doc}).iter_errors(example)
    )
    accepted = api.client.post("/v1/jobs", json=example, headers=auth())
    assert accepted.status_code in (201, 429), accepted.text  # valid (429: alice's limit)


def test_events_progress_heartbeat_then_end(api: Api) -> None:
    import httpx

    job = api.store.create("alice", "followed", {"name": "followed", "stages": []})
    api.client.app.state.heartbeat_s = 0.5
    lines: list[str] = []
    with serve(api.client.app) as port:
        client = httpx.Client(base_url=f"http://127.0.0.1:{port}", headers=auth(), timeout=60)
        with client, client.stream("GET", f"/v1/jobs/{job.id}/events") as stream:
            assert stream.headers["content-type"].startswith("text/event-stream")
            for line in stream.iter_lines():
                lines.append(line)
                if line.startswith(": ping") and not any("cancelled" in x for x in lines):
                    assert client.post(f"/v1/jobs/{job.id}/cancel").status_code == 200
    events = [line.removeprefix("event: ") for line in lines if line.startswith("event: ")]
    assert events == ["progress", "progress", "end"], lines
    data = [json.loads(line.removeprefix("data: ")) for line in lines if line.startswith("data:")]
    assert [d["state"] for d in data] == ["queued", "cancelled", "cancelled"]
    assert lines.index(": ping") < lines.index("event: end")


def test_a_failed_job_shows_its_error_and_resume(api: Api) -> None:
    job = api.store.create("alice", "failing", {"name": "failing", "stages": []})
    api.store.update(job.id, state="failed", attempt=1, error="trainer died: exit code 1")
    status = api.client.get(f"/v1/jobs/{job.id}", headers=auth()).json()
    assert status["state"] == "failed" and status["error"] == "trainer died: exit code 1"
    assert status["actions"] == [
        {"name": "resume", "method": "POST", "href": f"/v1/jobs/{job.id}/resume"}
    ]
    failed = api.client.get("/v1/jobs?state=failed", headers=auth()).json()["items"]
    assert job.id in [j["id"] for j in failed]


def test_an_unexpected_error_is_a_problem_without_details(api: Api) -> None:
    job = api.store.create("alice", "odd", {"name": "odd", "stages": []})
    with sqlite3.connect(api.settings.db_url.removeprefix("sqlite:///")) as db:  # as if a
        db.execute("UPDATE jobs SET state = 'paused' WHERE id = ?", (job.id,))  # newer service
    client = TestClient(api.client.app, raise_server_exceptions=False)
    body = _problem(client.get(f"/v1/jobs/{job.id}", headers=auth()), 500)
    assert body["detail"] == "internal error (logged by the service)"
    assert "Traceback" not in json.dumps(body) and "paused" not in json.dumps(body)
    api.store.update(job.id, state="cancelled")
