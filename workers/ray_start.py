"""Start Ray for a driver, or join a running cluster.

    start_ray()                       # a local Ray, its daemons in a process group of their own
    start_ray("10.0.0.5:6379")        # join a cluster

With no address a driver joins only the cluster that ``RAY_ADDRESS`` names (as under a Ray job,
whose supervisor sets it); otherwise it starts a Ray of its own, never the cluster a ``ray
start`` left on the machine, which ``ray.init()`` alone would join unasked (a training run
beside someone else's head then dies with it).

A local Ray's daemons (GCS, raylet, and the workers the raylet starts) are children of the
driver. By default they share its process group, so a signal to the group (GNU ``timeout``,
``kill -- -PGID``) stops them together with the driver: the driver, asked to stop with a
checkpoint, then finds its node gone, and Ray's core worker, recovering the driver's own
objects from the dead node's object store, ends the process (status 1, no checkpoint). Ray
already keeps the daemons out of terminal Ctrl-C (it blocks SIGINT in them) and, on Windows,
starts them in a process group of their own where the kernel shares their fate with the
driver; :func:`start_ray` does the same on Linux, where Ray's daemons die with the driver
(``PR_SET_PDEATHSIG``): a group signal reaches the driver only, and the driver shuts them
down after its checkpoint.

A local Ray listens on 127.0.0.1 only (its GCS, raylet, object manager, agents, metrics
servers, workers): its node's address is 127.0.0.1. Ray keeps a loopback node address only
where Ray clusters are off (``ray_constants.ENABLE_RAY_CLUSTER``: off on macOS and Windows);
elsewhere it replaces it with the machine's address and its servers bind every interface or
that address. :func:`start_ray` turns clusters off while it starts a local Ray, for the driver
and (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``) for the daemons; joining a cluster is untouched.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Iterator

import ray

logger = logging.getLogger(__name__)

CLUSTERS_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
"""Ray's switch for clusters of several nodes (read when ``ray`` is imported)"""


def start_ray(address: str | None = None, **init_kwargs) -> None:
    """``ray.init`` joining ``address`` (else ``RAY_ADDRESS``), or starting a local Ray
    (without its dashboard) that listens on 127.0.0.1 only and whose daemons run in a process
    group of their own (see the module docstring); ``init_kwargs`` go to ``ray.init``."""
    init_kwargs.setdefault("logging_level", logging.WARNING)
    address = address or os.environ.get("RAY_ADDRESS") or "local"
    if address != "local":
        ray.init(address=address, **init_kwargs)
        return
    init_kwargs.setdefault("include_dashboard", False)
    with _daemons_in_their_own_process_group(), _node_on_loopback():
        ray.init(address="local", **init_kwargs)


@contextlib.contextmanager
def _node_on_loopback() -> Iterator[None]:
    """While open, Ray clusters are off in this process (``ray_constants``) and in the
    processes it starts (:data:`CLUSTERS_ENV`), so that a local Ray started now keeps 127.0.0.1
    as its node's address and binds loopback (see the module docstring)."""
    from ray._private import ray_constants

    flag = getattr(ray_constants, "ENABLE_RAY_CLUSTER", True)
    env = os.environ.get(CLUSTERS_ENV)
    ray_constants.ENABLE_RAY_CLUSTER = False
    os.environ[CLUSTERS_ENV] = "0"
    try:
        yield
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = flag
        if env is None:
            os.environ.pop(CLUSTERS_ENV, None)
        else:
            os.environ[CLUSTERS_ENV] = env


@contextlib.contextmanager
def _daemons_in_their_own_process_group() -> Iterator[None]:
    """While open, the processes Ray starts (``ray._private.services.ConsolePopen``) begin a
    process group of their own, where the kernel kills them with the driver; elsewhere (no
    such fate sharing, or a Ray without that class) nothing changes."""
    from ray._private import services, utils

    popen = getattr(services, "ConsolePopen", None)
    linux = sys.platform.startswith("linux")
    if popen is None or not linux or not utils.detect_fate_sharing_support():
        logger.debug("Ray's daemons share the driver's process group")
        yield
        return

    class OwnGroupPopen(popen):
        def __init__(self, *args, **kwargs) -> None:
            kwargs.setdefault("process_group", 0)
            super().__init__(*args, **kwargs)

    services.ConsolePopen = OwnGroupPopen
    try:
        yield
    finally:
        services.ConsolePopen = popen


__all__ = ["start_ray"]
