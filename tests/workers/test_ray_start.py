"""A local Ray started by ``start_ray`` runs its daemons in process groups apart from the
driver's, so a signal to the driver's group reaches the driver alone; the daemons still end
with the driver (real Ray, in a driver process of its own)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from gaitforge.service.jobs.procs import alive, descendants, pgid_of

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
    driver = subprocess.Popen([sys.executable, "-c", DRIVER], stdout=subprocess.PIPE,
                              text=True, start_new_session=True)  # fmt: skip
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
