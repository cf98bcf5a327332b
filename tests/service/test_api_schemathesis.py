"""Schemathesis against the app's own OpenAPI document: for every operation, generated inputs
(valid and invalid) never answer 500 and every response conforms to the document (status
codes, media types, schemas, headers). Schemathesis sends alice's bearer token (its auth
config for the document's ``bearer`` scheme); negative cases may leave it out or spoil it
(401).

The runner is real (its Ray connection the session's head) but not started, so generated
jobs that validate stay queued (and the per-owner limit answers 429 past 3): nothing heavy
runs for each generated POST. Bounded: a few examples per operation and mode, no deadline.

(Each operation's cases come from ``APIOperation.as_strategy`` under ``@given``:
schemathesis' lazy pytest loader does not run on pytest 9.)
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
import schemathesis
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import open_store
from hypothesis import HealthCheck, given, settings
from schemathesis import GenerationMode
from schemathesis.config import SchemathesisConfig
from schemathesis.specs.openapi.checks import positive_data_acceptance

from tests.service.api_support import ALICE, TOKENS, seed_job

MAX_EXAMPLES = int(os.environ.get("GAITFORGE_SCHEMATHESIS_EXAMPLES", "6"))
"""examples per operation and mode (more for a deeper search, by hand)"""
# the document only: this app is never started (its home is never touched)
_DOC = create_app(ServiceSettings(home=Path("/nonexistent/doc-only"), tokens=TOKENS)).openapi()
CASES = [
    pytest.param(method.upper(), path, mode, id=f"{method.upper()} {path} {mode.value}")
    for path, operations in _DOC["paths"].items()
    for method, operation in operations.items()
    for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE)
    if mode == GenerationMode.POSITIVE or operation.get("parameters") or "requestBody" in operation
]  # negative: where there is something to make invalid
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
