"""A local Ray head for the service: started by ``ray start --head`` in a session of its
own (so it outlives the service, even a ``kill -9`` of it), found again through
``{home}/ray.json``, stopped by its own processes.

    head, started = local_head(home)     # the running one, or a new one (about 7 s)
    stop_local_ray(home)                                  # `gaitforge serve --stop-ray`

The head listens on 127.0.0.1 only: its node address is 127.0.0.1, so its GCS, raylet, object
manager, dashboard (the jobs API), agents and metrics servers bind loopback (see
:func:`head_environment`). Every port it opens is free (so that it never collides with
another head on the machine), its temp dir is its own (``/tmp/gf-ray-<8 chars>``: socket
paths must stay short), and it runs with ``RAY_AUTH_MODE=token`` and a token generated once
and kept in ``{home}/ray-token`` (0600). Every process it starts (workers, job drivers, the
trainers) carries ``GAITFORGE_RAY_HEAD=<its temp dir>`` in its environment, so that a stop
finds them all, even once the head's own daemons died (:func:`head_death`).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from gaitforge.service.jobs.procs import (
    alive,
    descendants,
    group_alive,
    pgid_of,
    pids_naming,
    pids_with_env,
    signal_group,
)
from gaitforge.service.private_files import make_private_dir, write_private_file
from pydantic import BaseModel

if TYPE_CHECKING:
    from gaitforge.service.settings import ServiceSettings

logger = logging.getLogger(__name__)

STATE_FILE = "ray.json"
TOKEN_FILE = "ray-token"
LOCK_FILE = "ray.lock"
START_TIMEOUT_S = 90.0
"""how long ``ray start`` and the dashboard may take to come up"""
JOB_STOP_WAIT_S = 60
"""how long Ray's stop_job waits after SIGTERM before SIGKILL (Ray's default, 3 s, is shorter
than an iteration: the trainer's checkpoint on the way out would be lost)"""
HEAD_ENV = "GAITFORGE_RAY_HEAD"
"""the variable naming a head's temp dir in the environment of every process of that head"""
HEAD_DAEMONS = ("gcs_server", "raylet")
"""the daemons a head cannot lose: without either its jobs are gone"""
LEFTOVER_WAIT_S = 10.0
"""how long a stop waits for a head's workers and job drivers to end after SIGTERM (a trainer
writes its checkpoint) before SIGKILL"""


class RayError(RuntimeError):
    """Ray could not be started or reached (one line saying what and where)."""


class LocalHead(BaseModel):
    """A local head started for the service, as kept in ``{home}/ray.json``."""

    address: str
    """GCS address (``host:port``) that drivers and ``ray.init`` join"""
    dashboard_url: str
    """the jobs API, ``http://127.0.0.1:<port>``"""
    temp_dir: str
    """the head's ``--temp-dir`` (sessions, logs, sockets)"""
    pgid: int
    """the process group (and session) of the head's daemons"""
    num_cpus: int
    started_at: float
    """Unix time"""


def running_head(home: Path) -> LocalHead | None:
    """The head recorded in ``{home}/ray.json`` if its GCS and raylet run and its dashboard
    answers, else None."""
    head = read_head(home)
    if head is None or missing_daemons(head) or not dashboard_answers(head.dashboard_url):
        return None
    return head


def missing_daemons(head: LocalHead) -> list[str]:
    """The daemons of :data:`HEAD_DAEMONS` that no longer run for ``head``."""
    running = {_command_name(pid) for pid in head_processes(head)}
    return [name for name in HEAD_DAEMONS if name not in running]


def head_death(home: Path) -> str | None:
    """Why the local head of ``home`` is dead, in a few words (None: its GCS and raylet
    run); waits for a start or a stop of it that is under way."""
    with _locked(home):
        head = read_head(home)
        if head is None:
            return f"none is recorded in {home / STATE_FILE} (it was stopped)"
        missing = missing_daemons(head)
    if not missing:
        return None
    return f"its {' and '.join(missing)} ended (head {head.address}, temp dir {head.temp_dir})"


def read_head(home: Path) -> LocalHead | None:
    """The head recorded in ``{home}/ray.json`` (None: none, or unreadable)."""
    try:
        return LocalHead.model_validate_json((home / STATE_FILE).read_text())
    except (OSError, ValueError):
        return None


def dashboard_answers(url: str, timeout_s: float = 2.0) -> bool:
    """The dashboard at ``url`` answers ``/api/version`` (any HTTP status counts)."""
    try:
        with urllib.request.urlopen(f"{url}/api/version", timeout=timeout_s):
            return True
    except urllib.error.HTTPError:
        return True
    except (OSError, ValueError):
        return False


def read_token(home: Path) -> str:
    """The local head's token from ``{home}/ray-token``, generated (0600) if missing."""
    path = home / TOKEN_FILE
    if not path.exists():
        make_private_dir(home)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w") as file:
            file.write(secrets.token_hex(32) + "\n")
    return path.read_text().strip()


def free_ports(n: int) -> list[int]:
    """``n`` distinct TCP ports free on 127.0.0.1 now (held open together while chosen)."""
    with contextlib.ExitStack() as stack:
        ports = []
        for _ in range(n):
            sock = stack.enter_context(socket.socket(socket.AF_INET, socket.SOCK_STREAM))
            sock.bind(("127.0.0.1", 0))
            ports.append(sock.getsockname()[1])
    return ports


def local_head(home: Path) -> tuple[LocalHead, bool]:
    """``home``'s local head: the running one, else a new one (:func:`start_local_ray`);
    and whether it was started now.

    Raises:
        RayError: ``ray start`` failed or the dashboard did not come up.
    """
    with _locked(home):
        head = running_head(home)
        return (head, False) if head is not None else (_start(home), True)


def start_local_ray(home: Path, num_cpus: int | None = None) -> LocalHead:
    """Start a local head for ``home`` (``ray start --head``, about 7 s) and record it in
    ``{home}/ray.json``; an earlier head of ``home`` is stopped first. Starting and stopping
    take ``{home}/ray.lock`` (a stop waits for a start under way, then stops that head).

    Raises:
        RayError: ``ray start`` failed or the dashboard did not come up.
    """
    with _locked(home):
        return _start(home, num_cpus)


@contextlib.contextmanager
def _locked(home: Path) -> Iterator[None]:
    """Hold ``{home}/ray.lock`` (an exclusive ``flock``; not re-entrant)."""
    make_private_dir(home)
    fd = os.open(home / LOCK_FILE, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
    with os.fdopen(fd, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _start(home: Path, num_cpus: int | None = None) -> LocalHead:
    _stop(home)
    token = read_token(home)
    temp_dir = tempfile.mkdtemp(prefix="gf-ray-", dir="/tmp")
    gcs, dashboard, client, agent, agent_grpc, metrics, env_agent = free_ports(7)
    num_cpus = num_cpus or os.cpu_count() or 1
    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"
    command = [
        ray,
        "start",
        "--head",
        "--node-ip-address",
        "127.0.0.1",
        "--port",
        str(gcs),
        "--dashboard-host",
        "127.0.0.1",
        "--dashboard-port",
        str(dashboard),
        "--include-dashboard",
        "true",
        "--disable-usage-stats",
        "--num-cpus",
        str(num_cpus),
        "--temp-dir",
        temp_dir,
        "--ray-client-server-port",
        str(client),
        "--dashboard-agent-listen-port",
        str(agent),
        "--dashboard-agent-grpc-port",
        str(agent_grpc),
        "--metrics-export-port",
        str(metrics),
        "--runtime-env-agent-port",
        str(env_agent),
    ]
    env = head_environment(token, temp_dir)
    logger.info("starting a local Ray head (%d CPUs, temp dir %s)", num_cpus, temp_dir)
    proc = subprocess.Popen(
        command,
        env=env,
        start_new_session=True,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    head = LocalHead(
        address=f"127.0.0.1:{gcs}",
        dashboard_url=f"http://127.0.0.1:{dashboard}",
        temp_dir=temp_dir,
        pgid=proc.pid,
        num_cpus=num_cpus,
        started_at=time.time(),
    )
    make_private_dir(home)
    _write_head(home, head)  # first, so that stop_local_ray finds a head that half started
    try:
        output, _ = proc.communicate(timeout=START_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        _stop(home)
        raise RayError(f"ray start: no answer in {START_TIMEOUT_S:.0f} s") from None
    if proc.returncode != 0:
        _stop(home)
        tail = " | ".join(output.strip().splitlines()[-5:])
        raise RayError(f"ray start failed (exit {proc.returncode}): {tail}")
    current = Path(temp_dir) / "ray_current_cluster"
    if current.exists():  # the GCS address as Ray wrote it
        head.address = current.read_text().strip() or head.address
    if not head.address.startswith("127.0.0.1:"):
        logger.warning(
            "the local Ray head took the address %s, not 127.0.0.1: it may listen beyond loopback",
            head.address,
        )
    deadline = time.monotonic() + START_TIMEOUT_S
    while not dashboard_answers(head.dashboard_url):
        if time.monotonic() > deadline:
            _stop(home)
            raise RayError(f"Ray dashboard at {head.dashboard_url}: no answer")
        time.sleep(0.2)
    _write_head(home, head)
    logger.info("local Ray head up: %s, jobs API %s", head.address, head.dashboard_url)
    return head


def head_environment(token: str, temp_dir: str) -> dict[str, str]:
    """The environment of ``ray start --head`` (and so of every process of the head): this
    process's without another cluster's address or token file; token auth on; the head's
    mark (:data:`HEAD_ENV`); Ray clusters off; and free ports for the metrics servers of the
    autoscaler and the dashboard (Ray's defaults are fixed ports).

    With clusters off (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``, as on macOS) Ray keeps
    ``--node-ip-address 127.0.0.1`` as the node's address, and every server of the node binds
    loopback. With them on (Ray's default on Linux) its CLI replaces a loopback node address
    by the machine's (``services.resolve_ip_for_localhost``), and the GCS, raylet, object
    manager, dashboard agent, runtime env agent and metrics servers bind every interface or
    that address. Nothing else changes for a head of one node: only ``ray start --address``
    (adding a node) refuses to run with clusters off.
    """
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "RAY_AUTH_TOKEN_PATH")}
    autoscaler_metrics, dashboard_metrics = free_ports(2)
    env.update(
        {
            "RAY_AUTH_MODE": "token",
            "RAY_AUTH_TOKEN": token,
            HEAD_ENV: temp_dir,
            "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
            "AUTOSCALER_METRIC_PORT": str(autoscaler_metrics),
            "DASHBOARD_METRIC_PORT": str(dashboard_metrics),
        }
    )
    env.setdefault("RAY_JOB_STOP_WAIT_TIME_S", str(JOB_STOP_WAIT_S))
    return env


def _write_head(home: Path, head: LocalHead) -> None:
    tmp = home / f".{STATE_FILE}.tmp"
    write_private_file(tmp, head.model_dump_json(indent=2))
    tmp.replace(home / STATE_FILE)


def stop_local_ray(home: Path | ServiceSettings, grace_s: float = 3.0) -> bool:
    """Stop the local head of ``home`` (a directory, or settings: their ``home``): SIGTERM
    to its process group, SIGKILL after ``grace_s``; then SIGTERM to what is left of it
    (workers, job drivers: every process marked with :data:`HEAD_ENV`, found even when its
    daemons died first) and SIGKILL after :data:`LEFTOVER_WAIT_S`; ``ray.json`` is removed.
    Only processes of that head are touched (never ``ray stop``, which stops every head on
    the machine).

    Returns:
        True if a recorded head was found (running or not).
    """
    home = Path(home) if isinstance(home, str | os.PathLike) else Path(home.home)
    if not home.is_dir():
        return False
    with _locked(home):
        return _stop(home, grace_s)


def _stop(home: Path, grace_s: float = 3.0) -> bool:
    head = read_head(home)
    if head is None:
        return False
    ours = head_and_leftovers(head)
    if _group_is_head(head):
        signal_group(head.pgid, signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        while group_alive(head.pgid) and time.monotonic() < deadline:
            time.sleep(0.1)
        signal_group(head.pgid, signal.SIGKILL)
    _signal_each(alive(ours), signal.SIGTERM)  # workers, job drivers: a trainer checkpoints
    deadline = time.monotonic() + LEFTOVER_WAIT_S
    while (left := alive(ours)) and time.monotonic() < deadline:
        time.sleep(0.2)
    _signal_each(left, signal.SIGKILL)
    (home / STATE_FILE).unlink(missing_ok=True)
    shutil.rmtree(head.temp_dir, ignore_errors=True)
    logger.info("local Ray head %s stopped", head.address)
    return True


def head_and_leftovers(head: LocalHead) -> set[int]:
    """Every live process of ``head``: those naming its temp dir, those marked with it
    (:data:`HEAD_ENV`: workers and job drivers, which have groups and sessions of their own
    and outlive dead daemons), and their descendants."""
    ours = set(pids_naming(head.temp_dir)) | set(pids_with_env(HEAD_ENV, head.temp_dir))
    return ours | descendants(ours)


def _signal_each(pids: list[int], sig: signal.Signals) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, sig)


def _command_name(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def head_processes(head: LocalHead) -> list[int]:
    """The live daemons of ``head``: processes of its group (and session) that name its
    temp dir (so not a later group that reused the number)."""
    return [pid for pid in pids_naming(head.temp_dir) if pgid_of(pid) == head.pgid]


def _group_is_head(head: LocalHead) -> bool:
    return bool(head_processes(head))


def first_line(what: BaseException | str) -> str:
    """The first non-empty line of a text or an exception's message (an exception without
    one: its type's name)."""
    lines = [line.strip() for line in str(what).splitlines() if line.strip()]
    if lines:
        return lines[0]
    return type(what).__name__ if isinstance(what, BaseException) else ""
