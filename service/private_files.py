"""Files and folders the service keeps for its owner only: folders 0700, files 0600, made so
from the start (the umask can only take permissions away); what exists is left as it is."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

PRIVATE_DIR_MODE = 0o700
PRIVATE_FILE_MODE = 0o600


def make_private_dir(path: Path) -> Path:
    """Make folder ``path`` and the missing folders above it, each its owner's only (0700);
    folders that exist are left as they are. Returns ``path``."""
    missing = []
    folder = path
    while not folder.exists():
        missing.append(folder)
        if folder.parent == folder:
            break
        folder = folder.parent
    for folder in reversed(missing):
        folder.mkdir(mode=PRIVATE_DIR_MODE, exist_ok=True)
    return path


def write_private_file(path: Path, text: str) -> None:
    """Write ``text`` to ``path``, a file its owner's only (0600) if it is made now."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, PRIVATE_FILE_MODE)
    with os.fdopen(fd, "w") as file:
        file.write(text)


def create_private_file(path: Path) -> None:
    """Make ``path`` an empty file its owner's only (0600), and its missing folders (0700),
    unless it exists."""
    make_private_dir(path.parent)
    with contextlib.suppress(FileExistsError):
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, PRIVATE_FILE_MODE))
