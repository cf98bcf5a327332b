"""The OpenAPI document says what the service really accepts and answers, through a real
uvicorn: every documented request example is accepted when posted as its media type; every
read operation on a job with artifacts answers a documented media type, its body valid
against the documented schema (each server-sent event's data too); a catalogue scene asked
for on a backend it does not run on is a 409 naming the backends it runs on."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import pytest
import yaml
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore, open_store
from jsonschema import Draft202012Validator

from tests.service.api_support import CHECKPOINT, TOKENS, auth, seed_job, serve

PROBLEM = "application/problem+json"
NAMES = {
    "checkpoints": CHECKPOINT,
    "recordings": "iter-000002.mcap",
    "reports": f"evaluate-{CHECKPOINT}.json",
}


@dataclass
class Live:
    client: httpx.Client
    doc: dict[str, Any]
    store: JobStore
    job: JobRecord


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[Live]:
    """The app on a real uvicorn, a real store, a real (not started: jobs stay queued)
    runner, and a job of alice's with artifacts."""
    settings = ServiceSettings(
        home=tmp_path_factory.mktemp("api-documented"), tokens=TOKENS, max_jobs_per_owner=50
    )
    store = open_store(settings.db_url)
    job = seed_job(store, settings)
    app = create_app(settings, JobRunner(settings, store, ray_connection))
    with serve(app) as port:
        base = f"http://127.0.0.1:{port}"
        with httpx.Client(base_url=base, headers=auth(), timeout=60) as client:
            doc = client.get("/openapi.json").json()
            yield Live(client, doc, store, job)
    store.close()


def _validator(doc: dict[str, Any], schema: dict[str, Any]) -> Draft202012Validator:
    return Draft202012Validator({**schema, "components": doc["components"]})


def _examples(media: dict[str, Any]) -> list[Any]:
    """A media type's examples (``example`` and each of ``examples``)."""
    found = [media["example"]] if "example" in media else []
    found += [e["value"] for e in media.get("examples", {}).values() if "value" in e]
    return found


def _serialized(example: Any, media_type: str) -> bytes:
    """``example`` (the data the schema describes) as a client sends it as ``media_type``:
    JSON, or YAML (as schemathesis and other tools serialize a YAML body)."""
    if "yaml" in media_type:
        return yaml.safe_dump(example, sort_keys=False).encode()
    return json.dumps(example).encode()


def test_every_documented_request_example_is_accepted(live: Live) -> None:
    posted = 0
    for path, operations in live.doc["paths"].items():
        for method, operation in operations.items():
            content = operation.get("requestBody", {}).get("content", {})
            for media_type, media in content.items():
                examples = _examples(media)
                assert examples, (method, path, media_type)
                for example in examples:
                    errors = list(_validator(live.doc, media["schema"]).iter_errors(example))
                    assert not errors, (method, path, media_type, errors[0].message)
                    r = live.client.request(
                        method.upper(),
                        path,
                        content=_serialized(example, media_type),
                        headers={"Content-Type": media_type},
                    )
                    assert r.status_code in (200, 201, 202), (media_type, example, r.text)
                    posted += 1
    assert posted >= 3  # JSON and two YAML media types


def test_the_yaml_example_text_in_the_document_is_accepted(live: Live) -> None:
    body = live.doc["paths"]["/v1/jobs"]["post"]["requestBody"]
    text = body["description"].split("```yaml\n", 1)[1].split("```", 1)[0]
    r = live.client.post("/v1/jobs", content=text, headers={"Content-Type": "application/yaml"})
    assert r.status_code == 201, r.text
    assert yaml.safe_load(text) == body["content"]["application/yaml"]["example"]


def _read_operations(live: Live) -> Iterator[tuple[str, dict[str, Any]]]:
    """(path filled in, operation) of every GET with parameters that exist."""
    for path, operations in live.doc["paths"].items():
        if "get" not in operations or path in ("/openapi.json", "/docs"):
            continue
        filled = path.replace("{job_id}", live.job.id).replace(
            "/v1/scenes/{name}", "/v1/scenes/stand-2d"
        )
        for kind, name in NAMES.items():
            filled = filled.replace(f"/{kind}/{{name}}", f"/{kind}/{name}")
        yield filled, operations["get"]


def test_every_read_answers_a_documented_media_type_and_schema(live: Live) -> None:
    live.store.update(live.job.id, state="succeeded")  # its event stream ends at once
    checked = 0
    for path, operation in _read_operations(live):
        r = live.client.get(path)
        assert r.status_code == 200, (path, r.text)
        documented = operation["responses"]["200"].get("content", {"application/json": {}})
        media_type = r.headers["content-type"].split(";")[0].strip()
        assert media_type in documented, (path, media_type, list(documented))
        media = documented[media_type]
        schema = media.get("schema", {})
        if media_type == "application/json":
            errors = list(_validator(live.doc, schema).iter_errors(r.json()))
            assert not errors, (path, errors[0].message)
        elif media_type == "text/event-stream":
            _check_events(live, r.text, media)
        else:
            assert schema == {"type": "string", "format": "binary"}, (path, schema)
        checked += 1
    assert checked >= 12


def _check_events(live: Live, stream: str, media: dict[str, Any]) -> None:
    """Each event of ``stream`` (comments aside) as the media type's ``itemSchema`` says,
    its data (JSON) valid against the item's ``data.contentSchema``."""
    item = media["itemSchema"]
    data_schema = item["properties"]["data"]["contentSchema"]
    events = []
    for block in stream.strip().split("\n\n"):
        fields = dict(
            line.split(": ", 1) for line in block.splitlines() if not line.startswith(":")
        )
        if not fields:
            continue
        assert not list(_validator(live.doc, item).iter_errors(fields)), fields
        data = json.loads(fields["data"])
        errors = list(_validator(live.doc, data_schema).iter_errors(data))
        assert not errors, errors[0].message
        events.append(fields["event"])
    assert events == ["progress", "end"], stream
    whole = [
        dict(line.split(": ", 1) for line in block.splitlines() if not line.startswith(":"))
        for block in stream.strip().split("\n\n")
    ]
    whole = [event for event in whole if event]
    errors = list(_validator(live.doc, media["schema"]).iter_errors(whole))
    assert not errors, errors[0].message  # (OpenAPI 3.2: the schema covers the stream)


def test_documented_download_media_types_are_what_is_served(live: Live) -> None:
    paths = live.doc["paths"]
    for kind, name in NAMES.items():
        operation = paths[f"/v1/jobs/{{job_id}}/{kind}/{{name}}"]["get"]
        r = live.client.get(f"/v1/jobs/{live.job.id}/{kind}/{name}", headers={"Range": "bytes=0-3"})
        assert r.status_code == 206, r.text
        partial = operation["responses"]["206"]["content"]
        assert r.headers["content-type"].split(";")[0] in partial, (kind, list(partial))
        several = live.client.get(
            f"/v1/jobs/{live.job.id}/{kind}/{name}", headers={"Range": "bytes=0-1,4-5"}
        )
        assert several.headers["content-type"].split(";")[0] in partial, (kind, list(partial))


def test_a_scene_on_a_backend_it_does_not_run_on_is_409_naming_its_backends(live: Live) -> None:
    scenes = {s["name"]: s["backends"] for s in live.client.get("/v1/scenes").json()}
    only_mujoco = [name for name, backends in scenes.items() if backends == ["mujoco"]]
    assert "elbow-reach" in only_mujoco
    for name in only_mujoco[:3]:
        r = live.client.get(f"/v1/scenes/{name}", params={"backend": "opensim"})
        assert r.status_code == 409 and r.headers["content-type"] == PROBLEM, r.text
        problem = r.json()
        assert problem["type"] == "urn:gaitforge:problem:backend-not-supported"
        assert problem["detail"] == f"scene {name!r} runs on mujoco only, not on opensim"
    documented = live.doc["paths"]["/v1/scenes/{name}"]["get"]["responses"]
    assert "409" in documented
    r = live.client.get("/v1/scenes/elbow-reach", params={"backend": "mujoco"})
    assert r.status_code == 200 and r.json()["backend"] == "mujoco"
    bogus = live.client.get("/v1/scenes/elbow-reach", params={"backend": "bogus"})
    assert bogus.status_code == 422  # not a simulator at all: the query is invalid
