"""Processes found through ``/proc`` (Linux): by a text in their command line, by a variable
of their environment, by parent, by process group; used to stop exactly the processes of one
local Ray head. And the TCP sockets that processes listen on."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sys
from dataclasses import dataclass
from pathlib import Path

TCP_LISTEN = "0A"
"""the state of a listening socket in ``/proc/net/tcp`` and ``tcp6``"""


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


def pids_with_env(name: str, value: str) -> list[int]:
    """Live processes (not zombies, not this one) whose environment has ``name=value`` as they
    were started with it (``/proc/<pid>/environ``); other users' processes are not listed."""
    found = []
    wanted = f"{name}={value}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            marked = wanted in (entry / "environ").read_bytes().split(b"\0")
        except OSError:
            continue
        if marked and proc_state(int(entry.name)) not in (None, "Z"):
            found.append(int(entry.name))
    return found


@dataclass(frozen=True)
class ListeningSocket:
    """A TCP socket that a process listens on."""

    pid: int
    command: str
    """the process's name (``/proc/<pid>/comm``)"""
    host: str
    """the address it is bound to (``0.0.0.0`` or ``::``: every interface)"""
    port: int


def listening_sockets(pids: set[int]) -> list[ListeningSocket]:
    """The TCP sockets (IPv4 and IPv6) that processes ``pids`` listen on, matched through the
    socket inodes of their open files; processes gone or not readable are skipped."""
    listening = _listening_by_inode()
    found = []
    for pid in sorted(pids):
        try:
            command = Path(f"/proc/{pid}/comm").read_text().strip()
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if target.startswith("socket:[") and (inode := int(target[8:-1])) in listening:
                host, port = listening[inode]
                found.append(ListeningSocket(pid, command, host, port))
    return found


def _listening_by_inode() -> dict[int, tuple[str, int]]:
    """inode -> (address, port) of every listening TCP socket of the machine."""
    found: dict[int, tuple[str, int]] = {}
    for table, family in (("tcp", socket.AF_INET), ("tcp6", socket.AF_INET6)):
        try:
            lines = Path(f"/proc/net/{table}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) < 10 or fields[3] != TCP_LISTEN:
                continue
            address, port = fields[1].split(":")
            host = socket.inet_ntop(family, _address_bytes(address))
            found[int(fields[9])] = (host, int(port, 16))
    return found


def _address_bytes(hex_words: str) -> bytes:
    """An address of ``/proc/net/tcp{,6}`` (32-bit words in hex, each in the machine's byte
    order) as network-order bytes."""
    raw = bytes.fromhex(hex_words)
    if sys.byteorder == "big":
        return raw
    return b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
