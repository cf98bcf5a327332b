"""Reading a job's files for the API: the log from an offset, the metrics series, a
checkpoint's zip and a file's sha256 (computed once per version).

No symbolic link below a job's folder is ever followed. Every file is opened one path
component at a time from the job's folder, each with ``O_NOFOLLOW`` relative to the folder
opened before it, so a link at the file or in place of any folder above it (``run/``,
``checkpoints/``, ``downloads/``) is refused (:class:`NotServed`) instead of read, and a file
swapped for a link after it was checked is never opened (the response streams the descriptor
that was checked). A checkpoint's zip leaves links (and anything not a plain file or folder)
out, logging each; it is cached as ``downloads/<checkpoint>-<fingerprint>.zip``, the
fingerprint taking in every member's name, size, times and inode, so a checkpoint whose
files changed gets a new zip, and a link or other non-file in the cached zip's place is
replaced by a freshly built zip, never served.
"""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import re
import secrets
import stat
import threading
import time
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

_CHUNK = 1 << 20
_zip_lock = threading.Lock()
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
_FILE_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
"""``O_NONBLOCK``: a FIFO put in a file's place must not hang the open"""
_REFUSED = (errno.ELOOP, errno.ENOTDIR, errno.EMLINK)
"""what ``open(O_NOFOLLOW)`` of a link answers (Linux, macOS; FreeBSD: EMLINK)"""
SHA256_CACHE = "sha256"
"""the folder under a job's downloads where digests are kept"""


class NotServed(Exception):
    """A path below a job's folder that is a symbolic link, lies under one, or is not a
    plain file (a folder where a file should be, a FIFO, ...): never read for a response."""


@dataclass
class OpenedFile:
    """A plain file of a job, open for reading (``fd``) and checked: its ``stat`` is the
    descriptor's own (``fstat``). Close it (or use it as a context manager)."""

    fd: int
    stat: os.stat_result
    path: Path
    """where it was opened (for messages)"""

    def close(self) -> None:
        """Close the descriptor (once)."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def __enter__(self) -> OpenedFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def read_at(self, offset: int, size: int) -> bytes:
        """Up to ``size`` bytes from ``offset`` (the descriptor's position is not used)."""
        chunks = []
        while size > 0:
            chunk = os.pread(self.fd, min(size, _CHUNK), offset)
            if not chunk:
                break
            chunks.append(chunk)
            offset += len(chunk)
            size -= len(chunk)
        return b"".join(chunks)

    def read_all(self) -> bytes:
        """The whole file, as it is now."""
        return self.read_at(0, max(os.fstat(self.fd).st_size, 0))


def _parts_below(job_dir: Path, path: Path) -> tuple[str, ...]:
    """The components of ``path`` below ``job_dir`` (a path the layout built).

    Raises:
        NotServed: ``path`` is not below ``job_dir``, or has ``.``/``..`` components.
    """
    try:
        parts = path.relative_to(job_dir).parts
    except ValueError:
        raise NotServed(f"{path}: not in the job's folder") from None
    if not parts or any(part in (".", "..") for part in parts):
        raise NotServed(f"{path}: not a path below the job's folder")
    return parts


def _refusal(dir_fd: int, name: str, where: str) -> NotServed:
    """Why ``name`` (in the folder ``dir_fd``) could not be opened as it should be."""
    try:
        mode = os.stat(name, dir_fd=dir_fd, follow_symlinks=False).st_mode
    except OSError:
        mode = 0
    what = "a symbolic link" if stat.S_ISLNK(mode) else "not a plain file or folder"
    return NotServed(f"{where}: {what}; not served")


def _open_at(dir_fd: int, name: str, flags: int, where: str) -> int:
    """``name`` in the folder ``dir_fd``, opened with ``flags`` (which hold ``O_NOFOLLOW``).

    Raises:
        NotServed: ``name`` is a link (or not the kind ``flags`` asks for).
        FileNotFoundError: ``name`` is not there.
    """
    try:
        return os.open(name, flags, dir_fd=dir_fd)
    except OSError as exc:
        if exc.errno in _REFUSED:
            raise _refusal(dir_fd, name, where) from None
        raise


@contextmanager
def _job_folder(job_dir: Path, parts: tuple[str, ...], create: bool = False) -> Iterator[int]:
    """The folder ``job_dir/<parts...>`` open (its descriptor), each part opened without
    following a link; with ``create``, missing parts are made (mode 0755).

    Raises:
        NotServed: a part is a link or not a folder.
        FileNotFoundError: a part is missing (without ``create``).
    """
    fd = os.open(job_dir, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        for depth, part in enumerate(parts, start=1):
            where = "/".join(parts[:depth])
            if create:
                with suppress(FileExistsError):
                    os.mkdir(part, 0o755, dir_fd=fd)
            child = _open_at(fd, part, _DIR_FLAGS, where)
            os.close(fd)
            fd = child
        yield fd
    finally:
        os.close(fd)


def _open_regular(dir_fd: int, name: str, where: str, path: Path) -> OpenedFile:
    """The plain file ``name`` of folder ``dir_fd``, opened without following a link.

    Raises:
        NotServed: a link, a folder, a FIFO, ...
        FileNotFoundError: not there.
    """
    fd = _open_at(dir_fd, name, _FILE_FLAGS, where)
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise NotServed(f"{where}: not a plain file; not served")
    return OpenedFile(fd, info, path)


def open_job_file(job_dir: Path, path: Path) -> OpenedFile:
    """The plain file ``path`` below ``job_dir``, open, with no link followed on the way.

    Raises:
        NotServed: ``path``, or a folder on the way to it, is a symbolic link, or ``path``
            is not a plain file.
        FileNotFoundError: it is not there.
    """
    parts = _parts_below(job_dir, path)
    with _job_folder(job_dir, parts[:-1]) as dir_fd:
        return _open_regular(dir_fd, parts[-1], "/".join(parts), path)


def stat_job_file(job_dir: Path, path: Path) -> os.stat_result | None:
    """The stat of the plain file ``path`` below ``job_dir`` as :func:`open_job_file` opens
    it (None: missing, a link, under a link, or not a plain file)."""
    try:
        with open_job_file(job_dir, path) as opened:
            return opened.stat
    except (FileNotFoundError, NotServed):
        return None


def read_log(job_dir: Path, path: Path, offset: int, limit: int) -> tuple[str, int, bool]:
    """Up to ``limit`` bytes of ``path`` from ``offset``, as text ending on a whole UTF-8
    character: (text, next offset, whether that is the end of the file). A missing file
    reads as empty.

    Raises:
        NotServed: the log is a link (or under one).
    """
    try:
        opened = open_job_file(job_dir, path)
    except FileNotFoundError:
        return "", offset, True
    with opened:
        size = opened.stat.st_size
        start = min(offset, size)
        data = opened.read_at(start, min(limit, size - start))
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


def read_metrics(job_dir: Path, path: Path, since: int | None) -> list[dict[str, Any]]:
    """The metrics points (one JSON object a line) after iteration ``since``; a line being
    written (not yet whole) is skipped.

    Raises:
        NotServed: the metrics file is a link (or under one).
    """
    try:
        with open_job_file(job_dir, path) as opened:
            lines = opened.read_all().decode("utf-8", errors="replace").splitlines()
    except FileNotFoundError:
        return []
    points = []
    for line in lines:
        try:
            point = json.loads(line)
        except (json.JSONDecodeError, ValueError, RecursionError):
            continue
        if not isinstance(point, dict):
            continue
        iteration = point.get("iteration")
        if since is not None and isinstance(iteration, int) and iteration <= since:
            continue
        points.append(point)
    return points


def sha256_of(job_dir: Path, opened: OpenedFile, cache: Path) -> str:
    """The sha256 (hex) of the open file ``opened``, cached in the folder ``cache`` below
    ``job_dir`` against its size, mtime and inode (a link at the cache is neither read nor
    written through: the digest is then computed each time)."""
    info = opened.stat
    version = f"{info.st_size} {info.st_mtime_ns} {info.st_ino}"
    relative = "/".join(_parts_below(job_dir, opened.path))
    name = f"{hashlib.sha256(relative.encode()).hexdigest()[:32]}.sha256"
    parts = _parts_below(job_dir, cache)
    with (
        suppress(FileNotFoundError, NotServed, ValueError),
        open_job_file(job_dir, cache / name) as cached,
    ):
        known_version, digest = cached.read_all().decode().rsplit(" ", 1)
        if known_version == version:
            return digest
    h = hashlib.sha256()
    offset = 0
    while chunk := os.pread(opened.fd, _CHUNK, offset):
        h.update(chunk)
        offset += len(chunk)
    digest = h.hexdigest()
    try:
        with _job_folder(job_dir, parts, create=True) as cache_fd:
            _write_atomic(cache_fd, name, f"{version} {digest}".encode())
    except NotServed as exc:
        logger.warning("sha256 cache: %s", exc)
    return digest


def _write_atomic(dir_fd: int, name: str, data: bytes) -> None:
    """``data`` as ``name`` in folder ``dir_fd``: a new temporary file, then renamed over
    whatever is there (a link there is replaced, not written through)."""
    tmp = f".{name}.{secrets.token_hex(6)}"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644, dir_fd=dir_fd)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, name, src_dir_fd=dir_fd, dst_dir_fd=dir_fd)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp, dir_fd=dir_fd)
        raise


@dataclass(frozen=True)
class _Member:
    """A plain file of a checkpoint: its name in the zip, its folder and name, its lstat."""

    arcname: str
    dir_fd: int
    name: str
    info: os.stat_result


def _members(dir_fd: int, prefix: str, where: str) -> Iterator[_Member]:
    """The plain files below the folder ``dir_fd`` (by name, depth first); links and other
    non-files are left out, each logged. The folder descriptors live while iterating."""
    for name in sorted(os.listdir(dir_fd)):
        info = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
        inner = f"{where}/{name}"
        if stat.S_ISREG(info.st_mode):
            yield _Member(f"{prefix}/{name}", dir_fd, name, info)
        elif stat.S_ISDIR(info.st_mode):
            try:
                sub = _open_at(dir_fd, name, _DIR_FLAGS, inner)
            except (NotServed, FileNotFoundError) as exc:  # swapped meanwhile
                logger.warning("checkpoint zip: %s: left out (%s)", inner, exc)
                continue
            try:
                yield from _members(sub, f"{prefix}/{name}", inner)
            finally:
                os.close(sub)
        else:
            what = "a symbolic link" if stat.S_ISLNK(info.st_mode) else "not a plain file"
            logger.warning("checkpoint zip: %s is %s: left out", inner, what)


def _fingerprint(members: list[_Member]) -> str:
    """16 hex digits that change when any member's name, size, times or inode do."""
    h = hashlib.sha256()
    for m in members:
        i = m.info
        h.update(
            f"{m.arcname}\0{i.st_size}\0{i.st_mtime_ns}\0{i.st_ctime_ns}\0{i.st_ino}\n".encode()
        )
    return h.hexdigest()[:16]


def checkpoint_stat(job_dir: Path, checkpoint: Path) -> tuple[int, float]:
    """(bytes of the checkpoint folder's plain files, links left out; the folder's mtime).

    Raises:
        NotServed: the checkpoint folder is a link or under one.
        FileNotFoundError: it went away.
    """
    parts = _parts_below(job_dir, checkpoint)
    with _job_folder(job_dir, parts) as ckpt_fd:
        size = sum(m.info.st_size for m in _members(ckpt_fd, checkpoint.name, "/".join(parts)))
        return size, os.fstat(ckpt_fd).st_mtime


def checkpoint_zip(job_dir: Path, checkpoint: Path, downloads: Path) -> OpenedFile:
    """The zip of the checkpoint folder's plain files (links left out), open: the cached
    ``downloads/<checkpoint>-<fingerprint>.zip`` if there is one for the checkpoint as it is
    now, else built there (a temporary file, then renamed: readers see a whole zip or none;
    zips of the checkpoint as it was are removed).

    Raises:
        NotServed: the checkpoint or downloads folder is a link (or under one), or a
            folder is where the zip would go.
        FileNotFoundError: the checkpoint went away (rotated out) while it was zipped.
    """
    ckpt_parts = _parts_below(job_dir, checkpoint)
    where = "/".join(ckpt_parts)
    with _job_folder(job_dir, ckpt_parts) as ckpt_fd:
        fingerprint = _fingerprint(list(_members(ckpt_fd, checkpoint.name, where)))
    name = f"{checkpoint.name}-{fingerprint}.zip"
    with _zip_lock, _job_folder(job_dir, _parts_below(job_dir, downloads), create=True) as out:
        try:
            return _open_regular(out, name, f"downloads/{name}", downloads / name)
        except FileNotFoundError:
            pass
        except NotServed as exc:
            logger.warning("checkpoint zip: %s; building it again in its place", exc)
        with _job_folder(job_dir, ckpt_parts) as ckpt_fd:
            _build_zip(out, name, _members(ckpt_fd, checkpoint.name, where))
        _remove_stale_zips(out, checkpoint.name, keep=name)
        logger.info("built %s", downloads / name)
        return _open_regular(out, name, f"downloads/{name}", downloads / name)


def _build_zip(out_fd: int, name: str, members: Iterator[_Member]) -> None:
    """Zip ``members`` into ``name`` in folder ``out_fd`` (a temporary file, then renamed
    over whatever is at ``name``, a link included).

    Raises:
        NotServed: a folder is at ``name``.
    """
    tmp = f".{name}.{secrets.token_hex(6)}"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644, dir_fd=out_fd)
    try:
        with os.fdopen(fd, "wb") as f, zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as zf:
            for member in members:
                try:
                    opened = _open_regular(member.dir_fd, member.name, member.arcname, Path())
                except NotServed as exc:  # swapped for a link since it was listed
                    logger.warning("checkpoint zip: %s: left out", exc)
                    continue
                with opened, zf.open(_zip_info(member.arcname, opened.stat), "w") as entry:
                    offset = 0
                    while chunk := os.pread(opened.fd, _CHUNK, offset):
                        entry.write(chunk)
                        offset += len(chunk)
        try:
            os.replace(tmp, name, src_dir_fd=out_fd, dst_dir_fd=out_fd)
        except IsADirectoryError:
            raise NotServed(f"downloads/{name}: a folder; not served") from None
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp, dir_fd=out_fd)
        raise


def _zip_info(arcname: str, info: os.stat_result) -> zipfile.ZipInfo:
    """A zip entry for a plain file (its mtime, not before 1980, and mode), deflated."""
    when = max(time.localtime(info.st_mtime)[:6], (1980, 1, 1, 0, 0, 0))
    entry = zipfile.ZipInfo(arcname, when)
    entry.external_attr = (stat.S_IFREG | stat.S_IMODE(info.st_mode)) << 16
    entry.compress_type = zipfile.ZIP_DEFLATED
    entry.file_size = info.st_size
    return entry


def _remove_stale_zips(out_fd: int, checkpoint: str, keep: str) -> None:
    """Remove the zips of ``checkpoint`` other than ``keep`` (as it was before: older
    fingerprints, or the unfingerprinted name); a link there is removed, not followed."""
    stale = re.compile(rf"{re.escape(checkpoint)}(-[0-9a-f]{{16}})?\.zip")
    for entry in os.listdir(out_fd):
        if entry != keep and stale.fullmatch(entry):
            with suppress(FileNotFoundError, IsADirectoryError, PermissionError):
                os.unlink(entry, dir_fd=out_fd)
