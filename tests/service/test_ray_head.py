"""The service's local Ray head listens on loopback only: every process of it, workers and a
job's driver included (a real head, a real job)."""

from __future__ import annotations

import ipaddress
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from gaitforge.service.jobs.procs import descendants, listening_sockets, pids_naming
from gaitforge.service.jobs.ray_cluster import RayConnection, read_head

DRIVER = (
    "import time, ray; ray.init(); ray.get(ray.remote(lambda: 1).remote()); "
    "print('up', flush=True); time.sleep(120)"
)
"""a job's driver that joins the head and has the raylet start a worker"""


def _is_loopback(host: str) -> bool:
    address = ipaddress.ip_address(host)
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


def _wait(what: str, check: Callable[[], Any], timeout_s: float, every_s: float = 0.2) -> Any:
    """Poll ``check`` until it returns something true (returned); fail naming ``what``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if found := check():
            return found
        time.sleep(every_s)
    pytest.fail(f"{what}: not within {timeout_s} s")


def test_the_local_head_and_its_workers_listen_on_loopback_only(
    ray_connection: RayConnection, ray_home: Path
) -> None:
    head = read_head(ray_home)
    assert head is not None and head.address.startswith("127.0.0.1:")
    client = ray_connection.client
    sid = client.submit_job(entrypoint=f'{sys.executable} -c "{DRIVER}"')
    try:
        _wait("the driver is up", lambda: "up" in client.get_job_logs(sid), 60)
        ours = set(pids_naming(head.temp_dir))
        sockets = listening_sockets(ours | descendants(ours))
    finally:
        client.stop_job(sid)
        _wait("the driver stopped", lambda: client.get_job_status(sid).is_terminal(), 60)
    commands = {s.command for s in sockets}
    assert {"gcs_server", "raylet"} <= commands, commands  # the head's servers were seen
    assert any(c.startswith("ray::") for c in commands), commands  # the agents' too
    assert len(sockets) >= 8, sockets
    beyond = [s for s in sockets if not _is_loopback(s.host)]
    assert not beyond, f"listening beyond loopback: {beyond}"
