"""A local Ray started by ``start_ray`` runs its daemons in process groups apart from the
driver's, so a signal to the driver's group reaches the driver alone; the daemons still end
with the driver; it listens on loopback only; and with no address it starts its own Ray
rather than join the cluster a ``ray start`` left on the machine (real Ray, in driver
processes of their own). The module starts such a cluster once, and beside it one driver
that started its own Ray; the loopback and the address tests only look at them, the signal
test then ends the driver (a driver ended before a test starts is started again).
"""

from __future__ import annotations

import ipaddress
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from gaitforge.service.jobs.local_cluster import LocalCluster
from gaitforge.service.jobs.procs import alive, descendants, listening_sockets, pgid_of

DRIVER = """
import time
import ray
from gaitforge.workers.ray_start import start_ray

start_ray(num_cpus=1)
ray.get(ray.remote(lambda: 1).remote())  # a worker started by the raylet too
print(ray.get_runtime_context().gcs_address, flush=True)
time.sleep(600)
"""


@dataclass
class Driver:
    """A driver process that started a local Ray with ``start_ray`` and ran a task on it."""

    process: subprocess.Popen
    gcs_address: str
    daemons: set[int]
    """its descendants once it was up: the Ray daemons and the worker"""


@dataclass
class MachineCluster:
    """A head started by ``ray start --head``, recorded as the machine's last cluster where
    ``ray start`` records it (the default temp dir, here ``env``'s RAY_TMPDIR)."""

    cluster: LocalCluster
    env: dict[str, str]
    """a driver's environment on this machine: its RAY_TMPDIR, Ray's token"""


@pytest.fixture(scope="module")
def machine_cluster() -> Iterator[MachineCluster]:
    with LocalCluster() as cluster, tempfile.TemporaryDirectory(prefix="gf-rt-") as tmp:
        cluster.start_head(num_cpus=0)
        (Path(tmp) / "ray").mkdir()
        (Path(tmp) / "ray" / "ray_current_cluster").write_text(cluster.address)
        yield MachineCluster(cluster, cluster.env({"RAY_TMPDIR": tmp}))


@pytest.fixture(scope="module")
def local_driver(machine_cluster: MachineCluster) -> Iterator[Callable[[], Driver]]:
    """``local_driver()``: the module's running driver (started if there is none, or if a
    test has ended it), on the machine with ``machine_cluster``; every one started is killed
    at the end, with its daemons."""
    started: list[Driver] = []

    def running() -> Driver:
        if started and started[-1].process.poll() is None:
            return started[-1]
        process = subprocess.Popen(
            [sys.executable, "-c", DRIVER],
            env=machine_cluster.env,
            stdout=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        address = process.stdout.readline().strip()
        driver = Driver(process, address, descendants({process.pid}))
        started.append(driver)
        assert address, f"the driver exited ({process.poll()})"
        return driver

    try:
        yield running
    finally:
        for driver in started:
            if driver.process.poll() is None:
                driver.process.kill()
            driver.process.wait(timeout=60)
            for pid in alive(driver.daemons):  # no need to wait for them to notice
                os.kill(pid, signal.SIGKILL)


def _command_name(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _is_loopback(host: str) -> bool:
    address = ipaddress.ip_address(host)
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


def test_a_local_ray_listens_on_loopback_only(local_driver: Callable[[], Driver]) -> None:
    driver = local_driver()
    pids = {driver.process.pid} | descendants({driver.process.pid})
    sockets = listening_sockets(pids)
    commands = {s.command for s in sockets}
    assert {"gcs_server", "raylet"} <= commands, commands  # the daemons' servers were seen
    assert len(sockets) >= 6, sockets
    beyond = [s for s in sockets if not _is_loopback(s.host)]
    assert not beyond, f"listening beyond loopback: {beyond}"


ADDRESS_OF = """
import ray
from gaitforge.workers.ray_start import start_ray

{start}
print(ray.get_runtime_context().gcs_address, flush=True)
"""


def _gcs_addresses_of_drivers(starts: list[tuple[str, dict[str, str]]]) -> list[str]:
    """The GCS address (host:port) each driver ends up on, run with its ``(start, env)``
    (one after the other: side by side is no faster on 2 cores)."""
    addresses = []
    for start, env in starts:
        driver = subprocess.run(
            [sys.executable, "-c", ADDRESS_OF.format(start=start)],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert driver.returncode == 0, driver.stderr[-2000:]
        addresses.append(driver.stdout.strip().splitlines()[-1])
    return addresses


def test_with_no_address_a_driver_starts_its_own_ray_not_the_machines_last_cluster(
    machine_cluster: MachineCluster, local_driver: Callable[[], Driver]
) -> None:
    """The module's driver ran ``start_ray(num_cpus=1)`` beside the recorded cluster."""
    cluster, env = machine_cluster.cluster.address, machine_cluster.env
    plain, joined = _gcs_addresses_of_drivers(
        [("ray.init()", env), ("start_ray()", {**env, "RAY_ADDRESS": cluster})]
    )
    assert plain == cluster, (
        "plain ray.init() joins the machine's last cluster (what the test guards against)"
    )
    assert local_driver().gcs_address != cluster
    assert joined == cluster, "RAY_ADDRESS (as under a Ray job) is still joined"


def test_a_signal_to_the_drivers_group_leaves_ray_to_the_driver_which_takes_it_down(
    local_driver: Callable[[], Driver],
) -> None:
    """It ends the module's driver."""
    driver = local_driver()
    daemons = descendants({driver.process.pid})
    names = {_command_name(pid) for pid in daemons}
    assert {"gcs_server", "raylet"} <= names, names
    outside = {pid for pid in daemons if pgid_of(pid) not in (None, driver.process.pid)}
    assert outside == {pid for pid in daemons if pgid_of(pid) is not None}, (
        "every Ray daemon runs outside the driver's process group"
    )
    os.killpg(driver.process.pid, signal.SIGTERM)  # as GNU timeout does
    driver.process.wait(timeout=60)
    gcs_and_raylet = {p for p in daemons if _command_name(p) in ("gcs_server", "raylet")}
    deadline = time.monotonic() + 30
    while alive(gcs_and_raylet) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not alive(gcs_and_raylet), "the daemons end with the driver"
