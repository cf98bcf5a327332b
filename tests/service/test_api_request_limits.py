"""Request bodies that would crash or stall the service are answered as problems, through a
real uvicorn: a job nested deeper than ``max_body_depth`` or holding a number longer than
``max_number_chars`` (JSON or YAML) is a 422 naming what is wrong, logged in one line with no
traceback; Python's recursion limit reached anywhere in handling a request is a 400; a body
that stops arriving is answered 408 within ``body_timeout_s``."""

from __future__ import annotations

import logging
import select
import socket
import time
from collections.abc import Iterator
from dataclasses import dataclass

import httpx
import pytest
from fastapi import FastAPI
from gaitforge.service.api import create_app
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import open_store

from tests.service.api_support import ALICE, TOKENS, auth, serve

PROBLEM = "application/problem+json"
BODY_TIMEOUT_S = 1.0


@dataclass
class Live:
    app: FastAPI
    port: int
    settings: ServiceSettings
    client: httpx.Client


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[Live]:
    """The app on a real uvicorn with the default parse limits and a 1 s body timeout; the
    runner is real but not started (nothing runs)."""
    settings = ServiceSettings(
        home=tmp_path_factory.mktemp("api-limits"), tokens=TOKENS, body_timeout_s=BODY_TIMEOUT_S
    )
    store = open_store(settings.db_url)
    app = create_app(settings, JobRunner(settings, store, ray_connection))

    def recurse(depth: int = 0) -> int:
        return recurse(depth + 1) + 1

    def recursing_route() -> dict:
        """Reaches Python's recursion limit, as deep input would in any handler."""
        return {"depth": recurse()}

    app.add_api_route("/v1/recursing", recursing_route, methods=["GET"])
    with serve(app) as port, httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as c:
        yield Live(app, port, settings, c)
    store.close()


def _refused(live: Live, body: str, media: str, caplog: pytest.LogCaptureFixture) -> dict:
    """POST ``body`` as a job: a 422 problem, logged without a traceback."""
    caplog.clear()
    with caplog.at_level(logging.INFO):
        started = time.monotonic()
        r = live.client.post("/v1/jobs", content=body, headers={**auth(), "Content-Type": media})
        elapsed = time.monotonic() - started
    assert r.status_code == 422, (r.status_code, r.text[:300])
    assert r.headers["content-type"] == PROBLEM
    assert elapsed < 10, elapsed
    assert "Traceback" not in caplog.text and not any(rec.exc_info for rec in caplog.records)
    assert len(caplog.text) < 2000, caplog.text[:2000]
    return r.json()


def _nested_json(levels: int) -> str:
    """A job whose stages nest ``levels`` mappings and lists deep in all."""
    return '{"name": "deep", "stages": ' + "[" * (levels - 1) + "]" * (levels - 1) + "}"


def _nested_yaml_flow(levels: int) -> str:
    return "name: deep\nstages: " + "[" * (levels - 1) + "]" * (levels - 1) + "\n"


def _nested_yaml_block(levels: int) -> str:
    lines = ["name: deep", "stages:"]
    lines += [" " * (2 * i) + "- " + ("" if i < levels - 2 else "1") for i in range(levels - 1)]
    return "\n".join(lines) + "\n"


NESTINGS = [
    pytest.param(media, make, levels, id=f"{make.__name__}-{levels}")
    for media, make, deepest in (
        ("application/json", _nested_json, 200_000),
        ("application/yaml", _nested_yaml_flow, 200_000),
        ("text/yaml", _nested_yaml_block, 600),  # indented deeper: over the body size limit
    )
    for levels in (65, 600, 1900, 200_000)
    if levels <= deepest
]


@pytest.mark.parametrize(("media", "make", "levels"), NESTINGS)
def test_a_body_nested_deeper_than_the_limit_is_422(
    live: Live, caplog: pytest.LogCaptureFixture, media: str, make, levels: int
) -> None:
    body = make(levels)
    assert len(body.encode()) <= live.settings.max_body_bytes
    problem = _refused(live, body, media, caplog)
    assert problem["errors"] == [{"field": "body", "message": problem["errors"][0]["message"]}]
    assert "nested more than 64 levels deep" in problem["detail"], problem
    assert "refused a job body: body: nested more than 64 levels deep" in caplog.text


def test_a_body_at_the_depth_limit_is_parsed(live: Live) -> None:
    r = live.client.post(
        "/v1/jobs", content=_nested_json(64), headers={**auth(), "Content-Type": "application/json"}
    )
    assert r.status_code == 422 and "nested" not in r.text, r.text  # the spec's own errors


@pytest.mark.parametrize("digits", [101, 4301, 5000])
@pytest.mark.parametrize("media", ["application/json", "application/yaml"])
@pytest.mark.parametrize("kind", ["int", "float", "negative"])
def test_a_number_longer_than_the_limit_is_422_naming_its_field(
    live: Live, caplog: pytest.LogCaptureFixture, digits: int, media: str, kind: str
) -> None:
    number = {
        "int": "7" * digits,
        "float": "1." + "5" * (digits - 2),
        "negative": "-" + "9" * digits,
    }
    body = f'{{"name": "big", "stages": [{{"scene": "stand-2d", "env_steps": {number[kind]}}}]}}'
    problem = _refused(live, body, media, caplog)
    chars = len(number[kind])
    assert problem["errors"] == [
        {"field": "stages.0.env_steps", "message": f"a number of {chars} characters; at most 100"}
    ]


def test_a_long_yaml_sexagesimal_integer_is_422_at_once(
    live: Live, caplog: pytest.LogCaptureFixture
) -> None:
    """``1:2:3...`` is an integer in YAML 1.1, its value 60 to the power of its parts."""
    body = "name: big\nseed: 1" + ":59" * 100_000 + "\n"
    problem = _refused(live, body, "application/yaml", caplog)
    assert problem["errors"][0]["field"] == "seed"


def test_a_long_number_as_a_yaml_key_is_422(live: Live, caplog: pytest.LogCaptureFixture) -> None:
    body = "name: big\nstages:\n  - " + "9" * 500 + ": 1\n"  # (a YAML key: 1024 at most)
    problem = _refused(live, body, "application/yaml", caplog)
    assert problem["errors"][0]["field"] == "stages.0"


def test_recursion_anywhere_in_a_request_is_a_400_without_traceback(
    live: Live, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.INFO):
        r = live.client.get("/v1/recursing", headers=auth())
    assert r.status_code == 400 and r.headers["content-type"] == PROBLEM, r.text
    assert r.json()["detail"] == "the request is nested too deeply to handle"
    assert "Traceback" not in caplog.text and not any(rec.exc_info for rec in caplog.records)
    assert "GET /v1/recursing: input nested too deeply" in caplog.text


def _stalled_post(port: int, declared: int, sent: bytes) -> tuple[bytes, float]:
    """POST a job declaring ``declared`` bytes and sending only ``sent``: what comes back
    before the service closes the connection, and when (s)."""
    request = (
        f"POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {ALICE}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {declared}\r\n"
        "Connection: close\r\n\r\n"
    ).encode()
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=BODY_TIMEOUT_S + 20) as sock:
        sock.sendall(request + sent)
        received = b""
        while chunk := sock.recv(65536):
            received += chunk
    return received, time.monotonic() - started


def test_a_stalled_body_is_answered_408_and_closed(live: Live) -> None:
    received, elapsed = _stalled_post(live.port, 100, b"{}")
    assert received.startswith(b"HTTP/1.1 408 "), received[:200]
    assert b"content-type: application/problem+json" in received.lower()
    assert b"connection: close" in received.lower()
    assert BODY_TIMEOUT_S * 0.9 <= elapsed < BODY_TIMEOUT_S + 10, elapsed


def test_a_body_trickling_past_the_timeout_is_408(live: Live) -> None:
    request = (
        f"POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {ALICE}\r\n"
        "Content-Type: application/json\r\nContent-Length: 50\r\n\r\n"
    ).encode()
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", live.port), timeout=30) as sock:
        sock.sendall(request)
        for _ in range(50):  # a byte every 0.3 s (15 s in all) until the service answers
            if select.select([sock], [], [], 0.3)[0]:
                break
            sock.sendall(b" ")
        received = sock.recv(65536)
    assert received.startswith(b"HTTP/1.1 408 "), received[:200]
    assert time.monotonic() - started < BODY_TIMEOUT_S + 10


def test_a_whole_body_in_time_is_read(live: Live) -> None:
    received, _ = _stalled_post(live.port, 2, b"{}")
    assert received.startswith(b"HTTP/1.1 422 "), received[:200]  # the spec's own errors
