"""``/v1/jobs/{id}/checkpoints``, ``/recordings`` and ``/reports``: list and download.

Only names the job's layout lists are served (``JobLayout.resolve_artifact``): a name is
looked up, never joined into a path, so ``../``, encoded and absolute names answer 404 and
read nothing. No symbolic link below the job's folder is followed (:mod:`.files`): a link at
an artifact, or in place of a folder above it, answers 404 like a missing artifact and is left
out of the listing; a checkpoint's zip leaves links out. Downloads stream the descriptor that
was checked (:class:`OpenedFileResponse`, HTTP Range) with the whole file's sha256 in
``X-Content-SHA256``; a checkpoint downloads as a zip built once into the job's downloads.
"""

from __future__ import annotations

import logging
import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal

import anyio
from fastapi import APIRouter, Request
from fastapi import Path as PathParam
from fastapi.responses import FileResponse
from gaitforge.service.api.deps import Layout, OwnedJob
from gaitforge.service.api.files import (
    SHA256_CACHE,
    NotServed,
    OpenedFile,
    checkpoint_stat,
    checkpoint_zip,
    open_job_file,
    sha256_of,
    stat_job_file,
)
from gaitforge.service.api.problems import ProblemError, problem_responses
from gaitforge.service.api.schemas import Artifact, ArtifactList
from gaitforge.service.jobs.layout import JobLayout
from starlette.types import Receive, Scope, Send

logger = logging.getLogger(__name__)

Kind = Literal["checkpoints", "recordings", "reports"]
SHA_HEADER = "X-Content-SHA256"
MEDIA_TYPES = {
    ".zip": "application/zip",
    ".mcap": "application/x-mcap",
    ".mp4": "video/mp4",
    ".json": "application/json",
}
Name = Annotated[str, PathParam(max_length=255, description="a name the listing gives")]

router = APIRouter(prefix="/v1/jobs/{job_id}", tags=["artifacts"], responses=problem_responses(401))


def _listing(layout: JobLayout, kind: Kind) -> list[tuple[str, Path]]:
    """(name, path) of each artifact of ``kind``, as the layout lists them."""
    if kind == "checkpoints":
        names = layout.checkpoint_names()
    else:
        files = layout.recording_files() if kind == "recordings" else layout.report_files()
        names = [p.name for p in files]
    found = []
    for name in names:
        path = layout.resolve_artifact(kind, name)
        if path is not None:
            found.append((name, path))
    return found


def _artifact(layout: JobLayout, kind: Kind, name: str, path: Path) -> Artifact | None:
    """The listing's entry for ``path`` (None: gone, a link, or under one)."""
    if kind == "checkpoints":
        try:
            size, mtime = checkpoint_stat(layout.dir, path)
        except (FileNotFoundError, NotServed):  # rotated out while listed, or a link
            return None
        media = MEDIA_TYPES[".zip"]
    else:
        info = stat_job_file(layout.dir, path)
        if info is None:
            return None
        size, mtime = info.st_size, info.st_mtime
        media = MEDIA_TYPES.get(path.suffix, "application/octet-stream")
    return Artifact(
        name=name,
        kind=kind,
        size_bytes=size,
        media_type=media,
        modified_at=datetime.fromtimestamp(mtime, UTC),
        href=f"/v1/jobs/{layout.job_id}/{kind}/{name}",
    )


def list_artifacts(job: OwnedJob, layout: Layout, kind: Kind) -> ArtifactList:
    """The job's artifacts of ``kind``."""
    items = [_artifact(layout, kind, n, p) for n, p in _listing(layout, kind)]
    return ArtifactList(job_id=job.id, kind=kind, items=[a for a in items if a is not None])


if not callable(getattr(FileResponse, "_open_file", None)):  # what the subclass overrides
    raise ImportError("starlette's FileResponse no longer opens files in _open_file")


class OpenedFileResponse(FileResponse):
    """A ``FileResponse`` (HTTP Range, ETag, Last-Modified) of a file the route has already
    opened and checked: it streams that descriptor and never opens the path again, so a
    file swapped for a link after the check is not read. The descriptor is closed once the
    response is sent."""

    def __init__(
        self, opened: OpenedFile, media_type: str, filename: str, headers: dict[str, str]
    ) -> None:
        super().__init__(
            opened.path,
            media_type=media_type,
            filename=filename,
            headers=headers,
            stat_result=opened.stat,
        )
        self.opened = opened

    @asynccontextmanager
    async def _open_file(self) -> AsyncIterator[anyio.AsyncFile[bytes]]:
        file = anyio.wrap_file(os.fdopen(os.dup(self.opened.fd), "rb"))
        try:
            await file.seek(0)
            yield file
        finally:
            with anyio.CancelScope(shield=True):
                await file.aclose()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        extensions = dict(scope.get("extensions") or {})
        extensions.pop("http.response.pathsend", None)  # a path would be opened again
        try:
            await super().__call__({**scope, "extensions": extensions}, receive, send)
        finally:
            self.opened.close()


def _open_artifact(layout: JobLayout, kind: Kind, name: str) -> OpenedFile:
    """The download of artifact ``name``, open (a checkpoint: its zip).

    Raises:
        ProblemError: 404 when the layout does not list it, it is gone, or it (or a folder
            above it) is a link.
    """
    missing = ProblemError(404, f"no {kind[:-1]} {name!r} in job {layout.job_id}")
    path = layout.resolve_artifact(kind, name)
    if path is None:
        raise missing
    try:
        if kind == "checkpoints":
            return checkpoint_zip(layout.dir, path, layout.downloads_dir)
        return open_job_file(layout.dir, path)
    except FileNotFoundError:
        raise ProblemError(404, f"{kind[:-1]} {name!r} is gone (rotated out)") from None
    except NotServed as exc:
        logger.warning("job %s: %s", layout.job_id, exc)
        raise missing from None


def download(request: Request, layout: Layout, kind: Kind, name: str) -> FileResponse:
    """The file of artifact ``name`` (404 unless the layout lists it and it is a plain file
    reached without a link)."""
    opened = _open_artifact(layout, kind, name)
    try:
        digest = sha256_of(layout.dir, opened, layout.downloads_dir / SHA256_CACHE)
        _check_range(request.headers.get("range"), opened.stat.st_size)
    except BaseException:
        opened.close()
        raise
    if kind == "checkpoints":
        media, filename = MEDIA_TYPES[".zip"], f"{name}.zip"
    else:
        media, filename = MEDIA_TYPES.get(opened.path.suffix, "application/octet-stream"), name
    return OpenedFileResponse(opened, media, filename, {SHA_HEADER: digest})


def _check_range(http_range: str | None, size: int) -> None:
    """A malformed (400) or unsatisfiable (416) Range header, as a problem."""
    if http_range is None:
        return
    from starlette.responses import MalformedRangeHeader, RangeNotSatisfiable

    try:
        FileResponse._parse_range_header(http_range, size)
    except MalformedRangeHeader as exc:
        raise ProblemError(400, f"Range: {exc.content}") from None
    except RangeNotSatisfiable:
        headers = {"Content-Range": f"bytes */{size}"}
        raise ProblemError(416, f"Range: past the end ({size} bytes)", headers=headers) from None


_BINARY = {"type": "string", "format": "binary"}
_REPORT_SCHEMA = {
    "type": "object",
    "description": "a checkpoint's evaluation (learner.evaluation.results.EvaluationReport): "
    "the results per mode at the scene's own target speed, and the speed sweep if asked for",
    "properties": {
        "checkpoint": {"type": ["string", "null"]},
        "env_steps": {"type": ["integer", "null"]},
        "scene": {"type": "string"},
        "backend": {"type": "string"},
        "seed": {"type": "integer"},
        "results": {"type": "object", "description": "mode -> its episodes' metrics"},
        "sweep": {"type": "array", "items": {"type": "object"}},
        "sweep_mode": {"type": ["string", "null"]},
        "stage": {"type": ["object", "null"]},
        "recording": {"type": ["string", "null"], "description": "MCAP of the first episode"},
        "video": {"type": ["string", "null"], "description": "MP4 of the first episode"},
    },
}
_MEDIA: dict[Kind, list[str]] = {
    "checkpoints": ["application/zip"],
    "recordings": ["application/x-mcap", "video/mp4"],
    "reports": ["application/json"],
}
_WHAT = {
    "checkpoints": "checkpoint (a zip of its directory)",
    "recordings": "recording (MCAP episode or MP4 video)",
    "reports": "evaluation report (JSON)",
}


def _download_doc(kind: Kind) -> dict[int | str, dict[str, Any]]:
    """The documented answers of a download: the file whole (200: a report as its JSON,
    anything else as bytes), or the ranges asked for (206: one range as the file's media
    type, several as ``multipart/byteranges``)."""
    headers = {
        SHA_HEADER: {"description": "sha256 (hex) of the whole file", "schema": {"type": "string"}},
        "Accept-Ranges": {"description": "bytes", "schema": {"type": "string"}},
    }
    whole = _REPORT_SCHEMA if kind == "reports" else _BINARY
    one_range = {"description": "the bytes of the range (of a report: not JSON on its own)"}
    partial = {media: {"schema": one_range} for media in _MEDIA[kind]}
    partial["multipart/byteranges"] = {"schema": {**_BINARY, "description": "several ranges"}}
    return {
        200: {
            "description": f"the {kind[:-1]}",
            "content": {media: {"schema": whole} for media in _MEDIA[kind]},
            "headers": headers,
        },
        206: {"description": "the requested byte ranges", "content": partial, "headers": headers},
        **problem_responses(400, 404, 416, 422),
    }


def _add_routes(kind: Kind) -> None:
    def listing(job: OwnedJob, layout: Layout) -> ArtifactList:
        return list_artifacts(job, layout, kind)

    def fetch(request: Request, job: OwnedJob, layout: Layout, name: Name) -> FileResponse:
        return download(request, layout, kind, name)

    listing.__doc__ = f"The job's {kind}, oldest first."
    fetch.__doc__ = f"Download a {_WHAT[kind]}; HTTP Range; sha256 in {SHA_HEADER}."
    router.add_api_route(
        f"/{kind}",
        listing,
        methods=["GET"],
        response_model=ArtifactList,
        summary=f"List {kind}",
        operation_id=f"list_{kind}",
        responses=problem_responses(404, 422),
    )
    router.add_api_route(
        f"/{kind}/{{name}}",
        fetch,
        methods=["GET"],
        response_class=FileResponse,
        summary=f"Download a {kind[:-1]}",
        operation_id=f"download_{kind[:-1]}",
        responses=_download_doc(kind),
    )


for _kind in ("checkpoints", "recordings", "reports"):
    _add_routes(_kind)
