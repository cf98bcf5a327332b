"""REST API security: 401 without a token on every route but /healthz (an unknown query
parameter too: nothing about the route's parameters before the token is checked), another
owner's job answers 404 like a missing one on every job route, artifact names that try to
leave the listing answer 404 and read nothing (through a real uvicorn, paths sent byte for
byte), the body size limit (413, declared and streamed), no redirect built from the Host
header (a trailing slash is a 404), and a 405's Allow naming every method of the path."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore, open_store

from tests.service.api_support import (
    BOB,
    CHECKPOINT,
    SECRET,
    TOKENS,
    auth,
    raw_get,
    raw_request,
    seed_job,
    serve,
)

PROBLEM = "application/problem+json"
PUBLIC = {"/healthz", "/openapi.json", "/docs"}
"""liveness and the API's documentation (a browser cannot send a bearer token to /docs)"""
NAMES = {
    "checkpoints": CHECKPOINT,
    "recordings": "iter-000002.mcap",
    "reports": f"evaluate-{CHECKPOINT}.json",
    "scenes": "stand-2d",
}


@dataclass
class Api:
    client: TestClient
    settings: ServiceSettings
    store: JobStore
    job: JobRecord


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[Api]:
    """The app on a real store and a real (not started: jobs stay queued) runner, with a job
    of alice's that has artifacts."""
    home = tmp_path_factory.mktemp("api-security")
    settings = ServiceSettings(home=home, tokens=TOKENS, max_body_bytes=4096)
    store = open_store(settings.db_url)
    runner = JobRunner(settings, store, ray_connection)
    job = seed_job(store, settings)
    with TestClient(create_app(settings, runner)) as client:
        yield Api(client, settings, store, job)
    store.close()


def _routes(api: Api) -> list[tuple[str, str]]:
    """(method, path with parameters filled: alice's job, names that exist) of every API
    route (the API's and its documentation's; not the pages, which answer people)."""
    out = []
    for route in iter_route_contexts(api.client.app.routes):  # included routers' too
        if not route.include_in_schema and route.path not in PUBLIC:
            continue  # the pages for people (tests/service/test_job_pages.py)
        path = route.path.replace("{job_id}", api.job.id)
        for kind, name in NAMES.items():
            path = path.replace(f"/{kind}/{{name}}", f"/{kind}/{name}")
        out.extend((method, path) for method in sorted(route.methods))
    return out


def test_every_route_but_healthz_needs_a_token(api: Api) -> None:
    routes = _routes(api)
    assert len(routes) >= 16
    for method, path in routes:
        for headers in ({}, auth("not-a-token"), {"Authorization": "Basic YTpi"}):
            r = api.client.request(method, path, headers=headers)
            if path in PUBLIC:
                assert r.status_code == 200, r.text
                continue
            assert r.status_code == 401, (method, path, r.status_code)
            assert r.headers["content-type"] == PROBLEM
            assert r.headers["www-authenticate"].startswith("Bearer")
            assert r.json()["status"] == 401


def test_an_unknown_query_parameter_without_a_token_is_401_telling_nothing(api: Api) -> None:
    routes = [(m, p) for m, p in _routes(api) if p not in PUBLIC and p != "/healthz"]
    assert len(routes) >= 16
    with serve(api.client.app) as port:
        for method, path in routes:
            for token in (None, "not-a-token"):
                headers = {} if token is None else auth(token)
                query = f"{path}?stat=queued&limit=x&since=-1"
                status, found, body = raw_request(port, method, query, headers)
                assert status == 401, (method, path, token, status, body)
                assert found["content-type"] == PROBLEM and "www-authenticate" in found
                problem = json.loads(body)
                assert set(problem) == {"type", "title", "status", "detail", "instance"}
                assert problem["detail"] in ("missing bearer token", "unknown bearer token")
        status, _, body = raw_request(port, "GET", "/v1/jobs?stat=queued", auth())
        assert status == 422 and b"allowed" in body  # with a token: what is allowed
        status, _, body = raw_request(port, "GET", "/healthz?x=1", {})
        assert status == 422 and b"allowed: none" in body  # public: nothing to hide


def test_a_trailing_slash_is_404_never_a_redirect_built_from_host(api: Api) -> None:
    paths = sorted({p.rstrip("/") + "/" for _, p in _routes(api)} | {"/v1/jobs/", "/v1/"})
    with serve(api.client.app) as port:
        for path in paths:
            for headers in ({"Host": "evil.example"}, {"Host": "evil.example", **auth()}, {}):
                status, found, body = raw_request(port, "GET", path, headers)
                assert status == 404, (path, headers, status, found)
                assert "location" not in found and found["content-type"] == PROBLEM
                assert b"evil.example" not in body


def test_a_method_not_allowed_names_every_method_of_the_path(api: Api) -> None:
    methods: dict[str, set[str]] = {}
    for method, path in _routes(api):
        methods.setdefault(path, set()).add(method)
    assert methods["/v1/jobs"] >= {"GET", "POST"}
    with serve(api.client.app) as port:
        for path, allowed in methods.items():
            for method in ("OPTIONS", "DELETE", "PATCH"):
                status, found, body = raw_request(port, method, path, auth())
                assert status == 405, (method, path, status, body)
                assert found["allow"] == ", ".join(sorted(allowed)), (method, path, found)
                assert found["content-type"] == PROBLEM


def test_another_owners_job_answers_as_a_missing_one(api: Api) -> None:
    missing = "j-000000000000"
    job_routes = [(m, p) for m, p in _routes(api) if api.job.id in p]
    assert len(job_routes) >= 12
    for method, path in job_routes:
        theirs = api.client.request(method, path, headers=auth(BOB))
        nobody = api.client.request(method, path.replace(api.job.id, missing), headers=auth(BOB))
        assert theirs.status_code == nobody.status_code == 404, (method, path, theirs.text)
        assert theirs.headers["content-type"] == PROBLEM
        assert theirs.json()["detail"].replace(api.job.id, missing) == nobody.json()["detail"]
        if method == "GET" and not path.endswith("/events"):  # (events: a queued job's stream)
            mine = api.client.get(path, headers=auth())
            assert mine.status_code == 200, (path, mine.text)


def test_owner_sees_only_own_jobs(api: Api) -> None:
    bobs = api.client.get("/v1/jobs", headers=auth(BOB)).json()
    assert bobs["total"] == 0 and bobs["items"] == []
    alices = api.client.get("/v1/jobs", headers=auth()).json()
    assert api.job.id in [j["id"] for j in alices["items"]]


TRAVERSALS = [
    "../../job.yaml",
    "../../../secret.txt",
    "..%2F..%2Fjob.yaml",
    "%2e%2e%2f%2e%2e%2fjob.yaml",
    "%2E%2E/%2E%2E/job.yaml",
    "%252e%252e%252f%252e%252e%252fjob.yaml",
    "..%252f..%252fjob.yaml",
    "%2Fetc%2Fpasswd",
    "/etc/passwd",
    "..\\..\\job.yaml",
    "..%5c..%5cjob.yaml",
    f"{CHECKPOINT}/../../../job.yaml",
    f"{CHECKPOINT}%2F..%2F..%2F..%2Fjob.yaml",
    f"{CHECKPOINT}/manifest.json",
    f"{CHECKPOINT}%2Fmanifest.json",
    "....//....//job.yaml",
    "secret.mcap",
    "secret.txt",
    "..",
    "%2e%2e",
    ".",
    "%00",
    f"{CHECKPOINT}%00.zip",
    "~/secret.txt",
]


def test_traversal_attempts_answer_404(api: Api) -> None:
    base = f"/v1/jobs/{api.job.id}"
    with serve(api.client.app) as port:
        status, _, body = raw_get(port, f"{base}/checkpoints/{CHECKPOINT}")
        assert status == 200 and body[:2] == b"PK"  # the real one is served
        for kind in ("checkpoints", "recordings", "reports"):
            for name in TRAVERSALS:
                status, headers, body = raw_get(port, f"{base}/{kind}/{name}")
                assert status in (404, 400), (kind, name, status)  # 400: a malformed path
                assert SECRET.encode() not in body and b"root:" not in body, (kind, name)
                assert headers.get("content-type") == PROBLEM, (kind, name, headers)
                if status == 400:
                    assert name.endswith(("%00", "%00.zip")), (kind, name)


def test_listings_name_only_artifacts(api: Api) -> None:
    base = f"/v1/jobs/{api.job.id}"
    names = {
        kind: [a["name"] for a in api.client.get(f"{base}/{kind}", headers=auth()).json()["items"]]
        for kind in ("checkpoints", "recordings", "reports")
    }
    assert names == {
        "checkpoints": [CHECKPOINT],
        "recordings": ["iter-000002.mcap", f"{CHECKPOINT}.mp4"],
        "reports": [f"evaluate-{CHECKPOINT}.json"],
    }


def test_body_over_the_limit_is_413(api: Api) -> None:
    big = b'{"name": "' + b"x" * 5000 + b'"}'
    declared = api.client.post("/v1/jobs", content=big, headers=auth())
    assert declared.status_code == 413 and declared.headers["content-type"] == PROBLEM

    def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it arrives
        yield b'{"name": "'
        for _ in range(10):
            yield b"x" * 1000
        yield b'"}'

    streamed = api.client.post("/v1/jobs", content=chunks(), headers=auth())
    assert streamed.status_code == 413, streamed.text
    assert streamed.json()["detail"] == "request body over 4096 bytes"
    with serve(api.client.app) as port:  # and through uvicorn, chunked
        import httpx

        r = httpx.post(f"http://127.0.0.1:{port}/v1/jobs", content=chunks(), headers=auth())
        assert r.status_code == 413 and r.headers["content-type"] == PROBLEM


def test_unknown_routes_and_methods_are_problems(api: Api) -> None:
    for method, path, status in (
        ("GET", "/nope", 404),
        ("DELETE", "/healthz", 405),
        ("PUT", "/v1/jobs", 405),
    ):
        r = api.client.request(method, path, headers=auth())
        assert r.status_code == status and r.headers["content-type"] == PROBLEM
        assert r.json()["status"] == status and r.json()["instance"] == path


def test_tokens_compare_every_entry() -> None:
    from gaitforge.service.api.auth import owner_of

    tokens = {"a" * 20: "alice", "b" * 20: "bob"}
    assert owner_of("b" * 20, tokens) == "bob"
    assert owner_of("b" * 19, tokens) is None and owner_of("", tokens) is None
    assert owner_of("é" * 3, tokens) is None


def test_no_tokens_generates_a_local_one(tmp_path) -> None:
    settings = ServiceSettings(home=tmp_path / "home")
    app = create_app(settings, runner=None)
    token = settings.token_file.read_text().strip()
    assert re.fullmatch(r"[A-Za-z0-9_-]{40,}", token)
    assert oct(settings.token_file.stat().st_mode & 0o777) == "0o600"
    assert app.state.tokens == {token: "local"}
    assert create_app(settings).state.tokens == {token: "local"}  # kept across restarts
    with pytest.raises(ValueError, match="host"):
        create_app(ServiceSettings(home=tmp_path / "h2", host="0.0.0.0"))


def test_lifespan_opens_store_connects_ray_and_runs_the_runner(service_settings) -> None:
    import time

    settings = service_settings.model_copy(update={"tokens": TOKENS})
    app = create_app(settings)  # no runner given: the lifespan makes one
    with TestClient(app) as client:
        runner = app.state.runner
        assert isinstance(runner, JobRunner) and app.state.store is runner.store
        deadline = time.monotonic() + 30
        while runner.last_pass_at is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert runner.last_pass_at is not None, runner.last_error
        assert client.get("/v1/jobs", headers=auth()).json()["total"] == 0
        assert client.get("/healthz").json()["status"] == "ok"
