"""Schemathesis against the app's own OpenAPI document: for every operation, generated inputs
(valid and invalid) never answer 500 and every response conforms to the document (status
codes, media types, schemas, headers). Schemathesis sends alice's bearer token (its auth
config for the document's ``bearer`` scheme); negative cases may leave it out or spoil it
(401).

Twice: through ASGI for every operation, and against the live service (a real uvicorn on
loopback, real HTTP) for the read operations and job submission, where valid cases name a
job that exists (with artifacts) and the document's own request examples are posted too.
Submission is capped: the service's own per-owner limit (3 queued jobs; 429 past it) and
a runner that is never started, so no generated job ever runs; the test checks both.

The runner is real (its Ray connection the session's head) but not started, so generated
jobs that validate stay queued (and the per-owner limit answers 429 past 3): nothing heavy
runs for each generated POST. Bounded: a few examples per operation and mode, no deadline.

(Each operation's cases come from ``APIOperation.as_strategy`` under ``@given``:
schemathesis' lazy pytest loader does not run on pytest 9.)
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import schemathesis
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobStore, open_store
from hypothesis import HealthCheck, given, settings
from schemathesis import GenerationMode
from schemathesis.config import SchemathesisConfig
from schemathesis.specs.openapi.checks import positive_data_acceptance

from tests.service.api_support import ALICE, TOKENS, seed_job, serve

MAX_EXAMPLES = int(os.environ.get("GAITFORGE_SCHEMATHESIS_EXAMPLES", "6"))
"""examples per operation and mode (more for a deeper search, by hand)"""
LIVE_EXAMPLES = int(os.environ.get("GAITFORGE_SCHEMATHESIS_LIVE_EXAMPLES", "6"))
"""examples per operation and mode against the live service (real HTTP: slower)"""
JOB_CAP = 3
"""queued jobs the live run's owner may have (the service's max_jobs_per_owner)"""
# the document only: this app is never started (its home is never touched)
_DOC = create_app(ServiceSettings(home=Path("/nonexistent/doc-only"), tokens=TOKENS)).openapi()
CASES = [
    pytest.param(method.upper(), path, mode, id=f"{method.upper()} {path} {mode.value}")
    for path, operations in _DOC["paths"].items()
    for method, operation in operations.items()
    for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE)
    if mode == GenerationMode.POSITIVE or operation.get("parameters") or "requestBody" in operation
]  # negative: where there is something to make invalid
LIVE_CASES = [
    pytest.param(method, path, mode, id=f"live {method} {path} {mode.value}")
    for method, path, mode in (case.values for case in CASES)
    if method == "GET" or (method, path) == ("POST", "/v1/jobs")
]
"""the read operations and job submission"""
SEMANTIC = {("POST", "/v1/jobs")}
"""operations whose input is checked beyond its JSON schema (a job's stages must fit one
policy lineage, its scenes run on its backend, ...): schema-valid input may answer 422"""


@pytest.fixture(scope="module")
def api_schema(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator:
    """The app's schema, loaded through ASGI from ``/openapi.json`` (calls go to the app)."""
    service = ServiceSettings(
        home=tmp_path_factory.mktemp("api-schemathesis"), tokens=TOKENS, max_jobs_per_owner=3
    )
    store = open_store(service.db_url)
    seed_job(store, service)  # a job with artifacts (its id is not known to the generator)
    app = create_app(service, JobRunner(service, store, ray_connection))
    config = SchemathesisConfig.from_str(f'[auth.openapi.bearer]\nbearer = "{ALICE}"\n')
    yield schemathesis.openapi.from_asgi("/openapi.json", app, config=config)
    store.close()


@pytest.mark.parametrize(("method", "path", "mode"), CASES)
def test_no_server_error_and_responses_conform(api_schema, method: str, path: str, mode) -> None:
    operation = api_schema[path][method]
    excluded = [positive_data_acceptance] if (method, path) in SEMANTIC else []

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(max_examples=MAX_EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))
    def run(case) -> None:
        case.call_and_validate(excluded_checks=excluded)

    run()


@dataclass
class LiveService:
    schema: schemathesis.specs.openapi.schemas.OpenApiSchema
    store: JobStore
    job_id: str
    """a job of alice's with artifacts (finished: its event stream ends at once)"""


@pytest.fixture(scope="module")
def live_service(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[LiveService]:
    """The app on a real uvicorn; its schema loaded from the live ``/openapi.json``."""
    service = ServiceSettings(
        home=tmp_path_factory.mktemp("api-schemathesis-live"),
        tokens=TOKENS,
        max_jobs_per_owner=JOB_CAP,
    )
    store = open_store(service.db_url)
    job = seed_job(store, service)
    store.update(job.id, state="succeeded")
    runner = JobRunner(service, store, ray_connection)  # never started: no job runs
    config = SchemathesisConfig.from_str(f'[auth.openapi.bearer]\nbearer = "{ALICE}"\n')
    with serve(create_app(service, runner)) as port:
        url = f"http://127.0.0.1:{port}/openapi.json"
        yield LiveService(schemathesis.openapi.from_url(url, config=config), store, job.id)
    assert runner.last_pass_at is None  # the runner never ran a pass: nothing started
    store.close()


def _check_cap(live: LiveService) -> None:
    """No more queued jobs than the cap, and none ever started."""
    jobs, total = live.store.list("alice", offset=0, limit=500)
    assert total < 500
    assert sum(j.state == "queued" for j in jobs) <= JOB_CAP
    assert all(j.attempt == 0 and j.started_at is None for j in jobs)


@pytest.mark.parametrize(("method", "path", "mode"), LIVE_CASES)
def test_live_no_server_error_and_responses_conform(
    live_service: LiveService, method: str, path: str, mode
) -> None:
    operation = live_service.schema[path][method]
    excluded = [positive_data_acceptance] if (method, path) in SEMANTIC else []

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(max_examples=LIVE_EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))
    def run(case) -> None:
        if mode == GenerationMode.POSITIVE and "job_id" in (case.path_parameters or {}):
            case.path_parameters["job_id"] = live_service.job_id  # a job that exists
        case.call_and_validate(excluded_checks=excluded, timeout=30)

    run()
    _check_cap(live_service)


def test_live_documented_request_examples_are_accepted(live_service: LiveService) -> None:
    """Each media type's own example is queued (201); the examples schemathesis composes from
    the schemas' examples conform (a composed job may be refused: 422)."""
    body = live_service.schema.raw_schema["paths"]["/v1/jobs"]["post"]["requestBody"]
    documented = {media: entry["example"] for media, entry in body["content"].items()}
    operation = live_service.schema["/v1/jobs"]["POST"]
    accepted: set[str] = set()
    strategies = operation.get_strategies_from_examples()
    assert 3 <= len(strategies) <= 30  # one POST each
    for strategy in strategies:
        queued, _ = live_service.store.list("alice", state="queued", offset=0, limit=500)
        for job in queued:  # room under the cap for the example
            live_service.store.update(job.id, state="cancelled")

        @given(case=strategy)
        @settings(max_examples=1, deadline=None, suppress_health_check=list(HealthCheck))
        def run(case) -> None:
            response = case.call_and_validate(
                excluded_checks=[positive_data_acceptance], timeout=30
            )
            if case.body == documented.get(case.media_type):
                assert response.status_code == 201, (case.media_type, response.text)
                accepted.add(case.media_type)

        run()
    assert accepted == set(documented)  # JSON and both YAML media types
    _check_cap(live_service)
