"""Reading a job's files for the API: the log from an offset, the metrics series, a
checkpoint's zip (built once, atomically) and a file's sha256 (computed once per version)."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
import threading
import zipfile
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

_CHUNK = 1 << 20
_zip_lock = threading.Lock()


def read_log(path: Path, offset: int, limit: int) -> tuple[str, int, bool]:
    """Up to ``limit`` bytes of ``path`` from ``offset``, as text ending on a whole UTF-8
    character: (text, next offset, whether that is the end of the file). A missing file
    reads as empty."""
    try:
        with path.open("rb") as f:
            size = os.fstat(f.fileno()).st_size
            start = min(offset, size)
            f.seek(start)
            data = f.read(limit)
    except FileNotFoundError:
        return "", offset, True
    end = start + len(data)
    if end < size:  # cut before a character split by the limit
        data = data[: len(data) - _partial_tail(data)]
        end = start + len(data)
    return data.decode("utf-8", errors="replace"), end, end >= size


def _partial_tail(data: bytes) -> int:
    """Bytes at the end of ``data`` that begin a UTF-8 character without finishing it."""
    for back in range(1, min(4, len(data)) + 1):
        byte = data[-back]
        if byte & 0xC0 != 0x80:  # a lead byte (or ASCII)
            need = 1 if byte < 0x80 else 2 if byte >> 5 == 6 else 3 if byte >> 4 == 14 else 4
            return back if need > back else 0
    return 0


def read_metrics(path: Path, since: int | None) -> list[dict[str, Any]]:
    """The metrics points (one JSON object a line) after iteration ``since``; a line being
    written (not yet whole) is skipped."""
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except FileNotFoundError:
        return []
    points = []
    for line in lines:
        try:
            point = json.loads(line)
        except json.JSONDecodeError:
            continue
        if not isinstance(point, dict):
            continue
        iteration = point.get("iteration")
        if since is not None and isinstance(iteration, int) and iteration <= since:
            continue
        points.append(point)
    return points


def sha256_of(path: Path, cache_dir: Path) -> str:
    """The sha256 (hex) of ``path``, cached in ``cache_dir`` against its size and mtime."""
    stat = path.stat()
    version = f"{stat.st_size} {stat.st_mtime_ns}"
    key = hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:32]
    cached = cache_dir / f"{key}.sha256"
    try:
        known_version, digest = cached.read_text().rsplit(" ", 1)
        if known_version == version:
            return digest
    except (FileNotFoundError, ValueError):
        pass
    digest = _hash_file(path)
    _write_atomic(cached, f"{version} {digest}".encode())
    return digest


def _hash_file(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def checkpoint_zip(checkpoint: Path, downloads: Path) -> Path:
    """``downloads/<checkpoint name>.zip``: the checkpoint directory's files, built the first
    time it is asked for (into a temporary file, then renamed: readers see a whole zip or
    none). A checkpoint never changes once written, so the zip stays valid.

    Raises:
        FileNotFoundError: the checkpoint went away (rotated out) while it was zipped.
    """
    target = downloads / f"{checkpoint.name}.zip"
    if target.exists():
        return target
    with _zip_lock:  # one build at a time (the web process is light; zips are small)
        if target.exists():
            return target
        downloads.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=downloads, prefix=f".{target.name}.")
        try:
            with os.fdopen(fd, "wb") as f, zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as zf:
                for file in sorted(checkpoint.rglob("*")):
                    if file.is_file():
                        zf.write(file, f"{checkpoint.name}/{file.relative_to(checkpoint)}")
            os.replace(tmp, target)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    logger.info("built %s", target)
    return target
