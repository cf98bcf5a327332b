"""Downloading a job's artifacts: names resolved against the service's listings (``latest``),
every file's sha256 checked against ``X-Content-SHA256``, checkpoints unzipped into
``DIR/<name>/`` so that ``gaitforge evaluate DIR/<name>`` loads them."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any

from gaitforge.service.client.http import ClientError, GaitforgeClient
from pydantic import BaseModel, Field

LATEST = "latest"


class Downloaded(BaseModel):
    """One file fetched and verified."""

    kind: str = Field(description="checkpoints, recordings or reports")
    name: str = Field(description="the artifact's name in the service's listing")
    path: Path = Field(description="where it is: a checkpoint's directory, else the file")
    bytes: int = Field(description="size of what was transferred (a checkpoint's zip)")
    sha256: str = Field(description="verified against the service's X-Content-SHA256")


def listed_names(listing: Any) -> list[str]:
    """The artifact names of a listing answer (``{"items": [{"name": ...}]}`` or a list)."""
    items = listing.get("items", []) if isinstance(listing, dict) else listing or []
    return [item["name"] if isinstance(item, dict) else str(item) for item in items]


def resolve_name(client: GaitforgeClient, job_id: str, kind: str, name: str) -> list[str]:
    """``name`` as the names to fetch: itself, or for ``latest`` the newest checkpoint, the
    recordings of the newest checkpoint's evaluation (MCAP and MP4; else the newest
    recording) or the newest report.

    Raises:
        ClientError: ``latest`` of a kind the job has none of.
    """
    if name != LATEST:
        return [name]
    names = listed_names(client.artifacts(job_id, kind))
    if not names:
        raise ClientError(f"job {job_id} has no {kind} yet")
    if kind == "checkpoints":
        return [sorted(names)[-1]]
    checkpoints = sorted(listed_names(client.artifacts(job_id, "checkpoints")))
    if checkpoints:
        final = [n for n in names if PurePosixPath(n).stem == checkpoints[-1]]
        if final:
            return final
    return [names[-1]]


def download(
    client: GaitforgeClient, job_id: str, kind: str, name: str, out_dir: Path
) -> list[Downloaded]:
    """Fetch ``kind/name`` (``latest`` allowed, see :func:`resolve_name`) into ``out_dir``.

    Raises:
        ApiError: the service has no such artifact (404) or refused.
        DigestMismatch: a file arrived different from its sha256 (nothing is kept).
        ClientError: a checkpoint's zip holds a path outside its directory.
    """
    done = []
    for each in resolve_name(client, job_id, kind, name):
        safe = PurePosixPath(each).name
        if kind == "checkpoints":
            archive = out_dir / f"{safe}.zip"
            size, sha = client.download(job_id, kind, each, archive)
            target = unzip_checkpoint(archive, out_dir / safe)
            archive.unlink()
        else:
            target = out_dir / safe
            size, sha = client.download(job_id, kind, each, target)
        done.append(Downloaded(kind=kind, name=each, path=target, bytes=size, sha256=sha))
    return done


def unzip_checkpoint(archive: Path, target: Path) -> Path:
    """Unpack a checkpoint's zip into ``target`` (replaced if there), whether its members
    sit at the top or under one folder of the checkpoint's name.

    Raises:
        ClientError: a member with an absolute path or ``..`` (nothing is unpacked).
    """
    with zipfile.ZipFile(archive) as zf:
        members = [m for m in zf.infolist() if not m.is_dir()]
        for member in members:
            parts = PurePosixPath(member.filename).parts
            if member.filename.startswith(("/", "\\")) or ".." in parts or ":" in parts[0]:
                raise ClientError(f"{archive}: member {member.filename!r} leaves its folder")
        tops = {PurePosixPath(m.filename).parts[0] for m in members}
        strip = len(tops) == 1 and all(len(PurePosixPath(m.filename).parts) > 1 for m in members)
        if target.exists():
            shutil.rmtree(target)
        target.mkdir(parents=True)
        for member in members:
            parts = PurePosixPath(member.filename).parts[1 if strip else 0 :]
            dest = target.joinpath(*parts)
            dest.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(member) as src, dest.open("wb") as dst:
                shutil.copyfileobj(src, dst)
    return target
