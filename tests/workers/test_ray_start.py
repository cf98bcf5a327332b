"""A local Ray started by ``start_ray`` runs its daemons in process groups apart from the
driver's, so a signal to the driver's group reaches the driver alone; the daemons still end
with the driver; it listens on loopback only; and with no address it starts its own Ray
rather than join the cluster a ``ray start`` left on the machine (real Ray, in driver
processes of their own)."""

from __future__ import annotations

import ipaddress
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from gaitforge.service.jobs.local_cluster import LocalCluster
from gaitforge.service.jobs.procs import alive, descendants, listening_sockets, pgid_of

DRIVER = """
import time
import ray
from gaitforge.workers.ray_start import start_ray

start_ray(num_cpus=1)
ray.get(ray.remote(lambda: 1).remote())  # a worker started by the raylet too
print("up", flush=True)
time.sleep(600)
"""


def _command_name(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def test_a_signal_to_the_drivers_group_leaves_ray_to_the_driver_which_takes_it_down() -> None:
    driver = subprocess.Popen(
        [sys.executable, "-c", DRIVER], stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        assert driver.stdout.readline().strip() == "up"
        daemons = descendants({driver.pid})
        names = {_command_name(pid) for pid in daemons}
        assert {"gcs_server", "raylet"} <= names, names
        outside = {pid for pid in daemons if pgid_of(pid) not in (None, driver.pid)}
        assert outside == {pid for pid in daemons if pgid_of(pid) is not None}, (
            "every Ray daemon runs outside the driver's process group"
        )
        os.killpg(driver.pid, signal.SIGTERM)  # as GNU timeout does
        driver.wait(timeout=60)
        gcs_and_raylet = {p for p in daemons if _command_name(p) in ("gcs_server", "raylet")}
        deadline = time.monotonic() + 30
        while alive(gcs_and_raylet) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not alive(gcs_and_raylet), "the daemons end with the driver"
    finally:
        if driver.poll() is None:
            driver.kill()


def _is_loopback(host: str) -> bool:
    address = ipaddress.ip_address(host)
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


def test_a_local_ray_listens_on_loopback_only() -> None:
    command = [sys.executable, "-c", DRIVER]
    driver = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, start_new_session=True)
    daemons: set[int] = set()
    try:
        assert driver.stdout.readline().strip() == "up"
        daemons = descendants({driver.pid})
        sockets = listening_sockets({driver.pid} | daemons)
    finally:
        driver.kill()
        driver.wait(timeout=60)
        for pid in alive(daemons):  # seen: no need to wait for them to notice the driver's end
            os.kill(pid, signal.SIGKILL)
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


def _gcs_address_of_driver(start: str, env: dict[str, str]) -> str:
    """The GCS address (host:port) a driver that runs ``start`` ends up on."""
    driver = subprocess.run(
        [sys.executable, "-c", ADDRESS_OF.format(start=start)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert driver.returncode == 0, driver.stderr[-2000:]
    return driver.stdout.strip().splitlines()[-1]


def test_with_no_address_a_driver_starts_its_own_ray_not_the_machines_last_cluster() -> None:
    with LocalCluster() as cluster, tempfile.TemporaryDirectory(prefix="gf-rt-") as tmp:
        cluster.start_head(num_cpus=0)
        # what `ray start --head` leaves in the default temp dir, here RAY_TMPDIR's
        (Path(tmp) / "ray").mkdir()
        (Path(tmp) / "ray" / "ray_current_cluster").write_text(cluster.address)
        env = cluster.env({"RAY_TMPDIR": tmp})
        assert _gcs_address_of_driver("ray.init()", env) == cluster.address, (
            "plain ray.init() joins the machine's last cluster (what the test guards against)"
        )
        assert _gcs_address_of_driver("start_ray(num_cpus=1)", env) != cluster.address
        joined = _gcs_address_of_driver("start_ray()", {**env, "RAY_ADDRESS": cluster.address})
        assert joined == cluster.address, "RAY_ADDRESS (as under a Ray job) is still joined"
