"""``/v1/jobs/{id}/checkpoints``, ``/recordings`` and ``/reports``: list and download.

Only names the job's layout lists are served (``JobLayout.resolve_artifact``): a name is
looked up, never joined into a path, so ``../``, encoded and absolute names answer 404 and
read nothing. Downloads are ``FileResponse``s (HTTP Range) with the whole file's sha256 in
``X-Content-SHA256``; a checkpoint downloads as a zip built once into the job's downloads.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Literal

from fastapi import APIRouter, Request
from fastapi import Path as PathParam
from fastapi.responses import FileResponse
from gaitforge.service.api.deps import Layout, OwnedJob
from gaitforge.service.api.files import checkpoint_zip, sha256_of
from gaitforge.service.api.problems import ProblemError, problem_responses
from gaitforge.service.api.schemas import Artifact, ArtifactList
from gaitforge.service.jobs.layout import JobLayout

Kind = Literal["checkpoints", "recordings", "reports"]
SHA_HEADER = "X-Content-SHA256"
MEDIA_TYPES = {".zip": "application/zip", ".mcap": "application/x-mcap", ".mp4": "video/mp4",
               ".json": "application/json"}  # fmt: skip
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


def _artifact(job_id: str, kind: Kind, name: str, path: Path) -> Artifact | None:
    try:
        if path.is_dir():
            files = [p.stat() for p in path.rglob("*") if p.is_file()]
            size, mtime = sum(s.st_size for s in files), path.stat().st_mtime
            media = MEDIA_TYPES[".zip"]
        else:
            stat = path.stat()
            size, mtime = stat.st_size, stat.st_mtime
            media = MEDIA_TYPES.get(path.suffix, "application/octet-stream")
    except FileNotFoundError:  # rotated out while listed
        return None
    return Artifact(
        name=name, kind=kind, size_bytes=size, media_type=media,
        modified_at=datetime.fromtimestamp(mtime, UTC),
        href=f"/v1/jobs/{job_id}/{kind}/{name}",
    )  # fmt: skip


def list_artifacts(job: OwnedJob, layout: Layout, kind: Kind) -> ArtifactList:
    """The job's artifacts of ``kind``."""
    items = [_artifact(job.id, kind, n, p) for n, p in _listing(layout, kind)]
    return ArtifactList(job_id=job.id, kind=kind, items=[a for a in items if a is not None])


def download(request: Request, layout: Layout, kind: Kind, name: str) -> FileResponse:
    """The file of artifact ``name`` (404 unless the layout lists it)."""
    path = layout.resolve_artifact(kind, name)
    if path is None:
        raise ProblemError(404, f"no {kind[:-1]} {name!r} in job {layout.job_id}")
    try:
        if path.is_dir():
            path = checkpoint_zip(path, layout.downloads_dir)
        digest = sha256_of(path, layout.downloads_dir / "sha256")
        size = path.stat().st_size
    except FileNotFoundError:
        raise ProblemError(404, f"{kind[:-1]} {name!r} is gone (rotated out)") from None
    _check_range(request.headers.get("range"), size)
    return FileResponse(
        path, media_type=MEDIA_TYPES.get(path.suffix, "application/octet-stream"),
        filename=path.name, headers={SHA_HEADER: digest},
    )  # fmt: skip


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


def _download_doc(kind: Kind, media: list[str]) -> dict:
    binary = {"schema": {"type": "string", "format": "binary"}}
    headers = {
        SHA_HEADER: {"description": "sha256 (hex) of the whole file", "schema": {"type": "string"}},
        "Accept-Ranges": {"description": "bytes", "schema": {"type": "string"}},
    }
    return {
        200: {"description": f"the {kind[:-1]}", "content": dict.fromkeys(media, binary),
              "headers": headers},
        206: {"description": "the requested byte range", "content": dict.fromkeys(media, binary),
              "headers": headers},
        **problem_responses(400, 404, 416, 422),
    }  # fmt: skip


_MEDIA: dict[Kind, list[str]] = {
    "checkpoints": ["application/zip"],
    "recordings": ["application/x-mcap", "video/mp4"],
    "reports": ["application/json"],
}
_WHAT = {"checkpoints": "checkpoint (a zip of its directory)",
         "recordings": "recording (MCAP episode or MP4 video)",
         "reports": "evaluation report (JSON)"}  # fmt: skip


def _add_routes(kind: Kind) -> None:
    def listing(job: OwnedJob, layout: Layout) -> ArtifactList:
        return list_artifacts(job, layout, kind)

    def fetch(request: Request, job: OwnedJob, layout: Layout, name: Name) -> FileResponse:
        return download(request, layout, kind, name)

    listing.__doc__ = f"The job's {kind}, oldest first."
    fetch.__doc__ = f"Download a {_WHAT[kind]}; HTTP Range; sha256 in {SHA_HEADER}."
    router.add_api_route(
        f"/{kind}", listing, methods=["GET"], response_model=ArtifactList,
        summary=f"List {kind}", operation_id=f"list_{kind}",
        responses=problem_responses(404, 422),
    )  # fmt: skip
    router.add_api_route(
        f"/{kind}/{{name}}", fetch, methods=["GET"], response_class=FileResponse,
        summary=f"Download a {kind[:-1]}", operation_id=f"download_{kind[:-1]}",
        responses=_download_doc(kind, _MEDIA[kind]),
    )  # fmt: skip


for _kind in ("checkpoints", "recordings", "reports"):
    _add_routes(_kind)
