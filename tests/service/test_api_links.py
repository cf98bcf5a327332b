"""No symbolic link below a job's folder is followed when the API serves its files (through a
real uvicorn): a link at a checkpoint member is left out of the zip (and logged), a link at a
cached zip, at a recording, a report, the log or the metrics, or in place of a folder above
them, is never read. Every link points at a file holding ``SECRET`` outside the job's folder
(or at one inside it that no listing names); no byte of it may reach a response."""

from __future__ import annotations

import io
import logging
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import anyio
import pytest
from fastapi import FastAPI
from gaitforge.service.api import create_app
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore, open_store

from tests.service.api_support import CHECKPOINT, SECRET, TOKENS, raw_get, seed_job, serve

REPORT = f"evaluate-{CHECKPOINT}.json"


@dataclass
class Served:
    app: FastAPI
    port: int
    settings: ServiceSettings
    store: JobStore
    outside: Path
    """a file holding SECRET outside every job's folder"""


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[Served]:
    """The app on a real uvicorn, a real store and a real (not started) runner."""
    home = tmp_path_factory.mktemp("api-links")
    settings = ServiceSettings(home=home, tokens=TOKENS)
    outside = home / "outside-secret.txt"
    outside.write_text(f"root:x:0:0 {SECRET}\n")
    store = open_store(settings.db_url)
    app = create_app(settings, JobRunner(settings, store, ray_connection))
    with serve(app) as port:
        yield Served(app, port, settings, store, outside)
    store.close()


def _job(served: Served) -> tuple[JobRecord, JobLayout]:
    """A fresh job of alice's with artifacts (each test spoils its own)."""
    job = seed_job(served.store, served.settings)
    return job, JobLayout(served.settings.artifacts, job.id)


def _get(served: Served, path: str) -> tuple[int, dict[str, str], bytes]:
    """GET ``path`` as alice; the response must not hold the secret."""
    status, headers, body = raw_get(served.port, path)
    assert SECRET.encode() not in body, (path, status, body[:200])
    return status, headers, body


def _zip_names(body: bytes) -> list[str]:
    with zipfile.ZipFile(io.BytesIO(body)) as zf:
        assert all(SECRET.encode() not in zf.read(n) for n in zf.namelist())
        return zf.namelist()


def _link(at: Path, target: Path) -> None:
    """``at`` replaced by a symbolic link to ``target``."""
    if at.is_dir() and not at.is_symlink():
        at.rename(at.with_name(f"{at.name}.real"))
    else:
        at.unlink(missing_ok=True)
    at.symlink_to(target)


def test_a_link_in_a_checkpoint_is_left_out_of_its_zip_and_logged(
    served: Served, caplog: pytest.LogCaptureFixture
) -> None:
    job, layout = _job(served)
    ckpt = layout.checkpoints_dir / CHECKPOINT
    (ckpt / "passwd").symlink_to(served.outside)
    (ckpt / "job.yaml").symlink_to(layout.job_file)  # inside the job, named by no listing
    (ckpt / "nested").symlink_to(served.outside.parent, target_is_directory=True)
    url = f"/v1/jobs/{job.id}/checkpoints/{CHECKPOINT}"
    with caplog.at_level(logging.WARNING, logger="gaitforge.service.api.files"):
        status, headers, body = _get(served, url)
    assert status == 200 and headers["content-type"] == "application/zip"
    assert _zip_names(body) == [
        f"{CHECKPOINT}/manifest.json",
        f"{CHECKPOINT}/meta.json",
        f"{CHECKPOINT}/policy.safetensors",
    ]
    logged = " ".join(r.getMessage() for r in caplog.records)
    for name in ("passwd", "job.yaml", "nested"):
        assert f"{CHECKPOINT}/{name} is a symbolic link: left out" in logged, logged
    plain = sum(p.stat().st_size for p in ckpt.iterdir() if not p.is_symlink())
    listed = raw_get(served.port, f"/v1/jobs/{job.id}/checkpoints")[2]
    assert f'"size_bytes":{plain},'.encode() in listed  # the plain files' bytes, no link's


def test_a_zip_cached_while_a_link_was_there_is_not_served_after(served: Served) -> None:
    job, layout = _job(served)
    ckpt = layout.checkpoints_dir / CHECKPOINT
    url = f"/v1/jobs/{job.id}/checkpoints/{CHECKPOINT}"
    (ckpt / "passwd").symlink_to(served.outside)
    assert _get(served, url)[0] == 200
    (ckpt / "passwd").unlink()
    status, _, body = _get(served, url)
    assert status == 200 and f"{CHECKPOINT}/passwd" not in _zip_names(body)
    (ckpt / "meta.json").write_text('{"env_steps": 512}')  # the checkpoint changed: a new zip
    status, _, body = _get(served, url)
    assert (
        zipfile.ZipFile(io.BytesIO(body)).read(f"{CHECKPOINT}/meta.json") == b'{"env_steps": 512}'
    )
    assert len(list(layout.downloads_dir.glob("*.zip"))) == 1  # the older zip removed


def test_a_link_in_place_of_the_cached_zip_is_rebuilt_not_served(served: Served) -> None:
    job, layout = _job(served)
    url = f"/v1/jobs/{job.id}/checkpoints/{CHECKPOINT}"
    layout.downloads_dir.mkdir(parents=True)
    (layout.downloads_dir / f"{CHECKPOINT}.zip").symlink_to(served.outside)  # the old name
    status, headers, body = _get(served, url)
    assert status == 200 and headers["content-type"] == "application/zip"
    assert len(_zip_names(body)) == 3
    cached = [p for p in layout.downloads_dir.iterdir() if p.suffix == ".zip"]
    assert len(cached) == 1 and not cached[0].is_symlink()  # the stale link is gone
    _link(cached[0], served.outside)  # the cache itself
    status, headers, body = _get(served, url)
    assert status == 200 and len(_zip_names(body)) == 3
    assert not cached[0].is_symlink()
    sha = layout.downloads_dir / "sha256"
    for digest in sha.iterdir():
        _link(digest, served.outside)
    status, headers, body = _get(served, url)  # a link at the digest cache: not read
    assert status == 200 and len(_zip_names(body)) == 3
    assert len(headers["x-content-sha256"]) == 64


def test_a_link_at_the_downloads_or_checkpoints_folder_is_refused(served: Served) -> None:
    job, layout = _job(served)
    url = f"/v1/jobs/{job.id}/checkpoints/{CHECKPOINT}"
    elsewhere = served.outside.parent / f"elsewhere-{job.id}"
    elsewhere.mkdir()
    (elsewhere / f"{CHECKPOINT}.zip").symlink_to(served.outside)
    _link(layout.downloads_dir, elsewhere)
    status, headers, _ = _get(served, url)
    assert status == 404 and headers["content-type"] == "application/problem+json"
    assert not list(elsewhere.glob("*.sha256")) and len(list(elsewhere.iterdir())) == 1
    layout.downloads_dir.unlink()
    inner = layout.dir / "copied-checkpoints"  # a link inside the job's folder: refused too
    (layout.checkpoints_dir).rename(inner)
    (inner / CHECKPOINT / "policy.safetensors").write_text(SECRET)
    layout.checkpoints_dir.symlink_to(inner, target_is_directory=True)
    assert _get(served, url)[0] == 404
    assert _get(served, f"/v1/jobs/{job.id}/checkpoints")[2].count(b'"items":[]') == 1


@pytest.mark.parametrize("kind", ["recordings", "reports"])
def test_a_link_at_a_recording_or_report_answers_404(served: Served, kind: str) -> None:
    job, layout = _job(served)
    if kind == "recordings":
        folder, name = layout.recordings_dir, "iter-000002.mcap"
    else:
        folder, name = layout.reports_dir, REPORT
    _link(folder / name, layout.job_file)  # a file of the job's own that no listing names
    status, headers, _ = _get(served, f"/v1/jobs/{job.id}/{kind}/{name}")
    assert status == 404 and headers["content-type"] == "application/problem+json"
    assert name.encode() not in _get(served, f"/v1/jobs/{job.id}/{kind}")[2]
    (folder / name).unlink()
    (folder / name).write_text(SECRET)  # the real folder, moved away, holds the secret
    _link(folder, folder.with_name(f"{folder.name}.real"))
    assert _get(served, f"/v1/jobs/{job.id}/{kind}/{name}")[0] == 404
    if kind == "recordings":
        _link(layout.run_dir, layout.dir / "run.real")  # a link further up
        assert _get(served, f"/v1/jobs/{job.id}/{kind}/{name}")[0] == 404


def test_a_link_at_the_log_or_metrics_answers_404(served: Served) -> None:
    job, layout = _job(served)
    served.outside.with_name("metrics-secret.jsonl").write_text(
        f'{{"iteration": 1, "secret": "{SECRET}"}}\n'
    )
    _link(layout.log_file, served.outside)
    _link(layout.metrics_file, served.outside.with_name("metrics-secret.jsonl"))
    for what in ("logs", "metrics"):
        status, headers, body = _get(served, f"/v1/jobs/{job.id}/{what}")
        assert status == 404 and headers["content-type"] == "application/problem+json", body
        assert b"not a plain file" in body


def test_a_file_swapped_for_a_link_after_it_was_opened_is_not_read(served: Served) -> None:
    """The response streams the descriptor that was checked, not the path again."""
    from gaitforge.service.api.files import open_job_file
    from gaitforge.service.api.routes_artifacts import OpenedFileResponse

    _, layout = _job(served)
    report = layout.reports_dir / REPORT
    opened = open_job_file(layout.dir, report)
    response = OpenedFileResponse(opened, "application/json", REPORT, {})
    _link(report, served.outside)
    sent: list[dict] = []

    async def receive() -> dict:
        await anyio.sleep(3600)
        return {"type": "http.disconnect"}

    async def send(message: dict) -> None:
        sent.append(message)

    scope = {"type": "http", "method": "GET", "headers": [], "asgi": {"spec_version": "2.4"}}
    anyio.run(response, scope, receive, send)
    body = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
    assert body == b'{"return": 1.5}' and SECRET.encode() not in body
    assert opened.fd == -1  # closed once sent
