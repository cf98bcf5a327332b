"""Processes found through ``/proc`` (Linux): by a text in their command line, by parent,
by process group; used to stop exactly the processes of one local Ray head."""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path


def signal_group(pgid: int, sig: signal.Signals) -> None:
    """Send ``sig`` to process group ``pgid`` (gone or not ours: nothing)."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


def group_alive(pgid: int) -> bool:
    """Some process of group ``pgid`` still exists."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def pgid_of(pid: int) -> int | None:
    """The process group of ``pid`` (None: gone)."""
    try:
        return os.getpgid(pid)
    except ProcessLookupError:
        return None


def alive(pids: set[int]) -> list[int]:
    """The processes of ``pids`` that still run (not zombies)."""
    return [pid for pid in pids if proc_state(pid) not in (None, "Z")]


def proc_state(pid: int) -> str | None:
    """The state letter of process ``pid`` (None: gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def descendants(pids: set[int]) -> set[int]:
    """Every process below ``pids`` (children, their children, ...)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    found: set[int] = set()
    todo = list(pids)
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found and child not in pids:
                found.add(child)
                todo.append(child)
    return found


def pids_naming(text: str) -> list[int]:
    """Live processes (not zombies) whose command line contains ``text``."""
    found = []
    needle = text.encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            named = needle in (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if named and proc_state(int(entry.name)) not in (None, "Z"):
            found.append(int(entry.name))
    return found
