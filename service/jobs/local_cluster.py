"""A Ray cluster of several nodes on this one machine, started with Ray's CLI as on real
machines (``ray start --head``, then ``ray start --address`` once per worker node): for the
multi-node test and the cluster benchmark.

    with LocalCluster() as cluster:                          # token-authenticated
        cluster.start_head(num_cpus=0, env={"GAITFORGE_PROFILES_DIR": "/driver/profiles"})
        a = cluster.add_node("node_a", num_cpus=1)           # custom resource {"node_a": 1}
        b = cluster.add_node("node_b", num_cpus=1)           # both start at once
        cluster.wait_for_nodes()                             # node ids, from Ray's state API
        cluster.actors("RolloutWorker")                      # live actors of that class
        cluster.kill_node(a)                                 # as if that machine were lost
    # every process of every node stopped, the temp dirs removed

Each node runs in a session of its own with its own short temp dir (``/tmp/gf-n-XXXXXXXX``:
socket paths must stay short) and free ports for everything it listens on, so that it can
be stopped alone (``ray stop`` stops every node of the machine) and another cluster may run
beside it. The head's dashboard (jobs and state APIs) listens on 127.0.0.1, every node runs
with ``RAY_AUTH_MODE=token`` and one token, and the head declares a node dead after about
:data:`HEALTH_CHECK_S` x 3 of silence (Ray's default: about 20 s).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gaitforge.service.jobs.local_ray import RayError, dashboard_answers, free_ports
from gaitforge.service.jobs.procs import alive, descendants, pids_naming

logger = logging.getLogger(__name__)

START_TIMEOUT_S = 90.0
"""how long ``ray start`` (and the head's dashboard, and the nodes' registration) may take"""
HEALTH_CHECK_S = 1.0
"""s between the head's health checks of each node (3 missed: the node is dead)"""
OBJECT_STORE_BYTES = 100 * 1024 * 1024
"""each node's object store (Ray's default, 30 % of memory per node, is far too much here)"""


@dataclass
class RayNode:
    """One node of a :class:`LocalCluster`: its ``ray start`` processes and what Ray calls it."""

    name: str
    """``head`` or the name given to :meth:`LocalCluster.add_node` (its custom resource)"""
    temp_dir: str
    num_cpus: int
    resources: dict[str, float]
    process: subprocess.Popen | None = None
    """``ray start`` while it runs (it returns once the node's daemons are up)"""
    node_id: str | None = None
    """Ray's node id (hex), known after :meth:`LocalCluster.wait_for_nodes`"""
    stopped: bool = False


@dataclass
class LocalCluster:
    """A head and worker nodes on this machine (see the module's docstring)."""

    token: str = field(default_factory=lambda: secrets.token_hex(32))
    """Ray's token (``RAY_AUTH_TOKEN``) of every node and client"""
    object_store_bytes: int = OBJECT_STORE_BYTES
    nodes: list[RayNode] = field(default_factory=list)
    address: str | None = None
    """the head's GCS address (``host:port``), once it is up"""
    dashboard_url: str | None = None
    """the head's jobs and state APIs (``http://127.0.0.1:<port>``), once it is up"""

    def __enter__(self) -> LocalCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    def env(self, extra: dict[str, str] | None = None) -> dict[str, str]:
        """The environment of a Ray process of this cluster: this one's, token auth on,
        without another cluster's address or token file, plus ``extra``."""
        env = {
            k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "RAY_AUTH_TOKEN_PATH")
        }
        env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=self.token, **(extra or {}))
        return env

    def start_head(
        self,
        num_cpus: int = 0,
        resources: dict[str, float] | None = None,
        env: dict[str, str] | None = None,
    ) -> RayNode:
        """``ray start --head`` (no CPUs for actors by default: it runs the drivers) with
        ``env`` added to its environment (its drivers and workers inherit it); returns once
        its dashboard answers (about 7 s).

        Raises:
            RayError: ``ray start`` failed or the dashboard did not come up.
        """
        gcs, dashboard, client = free_ports(3)
        health = str(round(HEALTH_CHECK_S * 1000))
        head_env = {
            "RAY_health_check_period_ms": health,
            "RAY_health_check_timeout_ms": health,
            "RAY_health_check_failure_threshold": "3",
            **(env or {}),
        }
        node = self._launch(
            "head",
            num_cpus,
            resources or {},
            head_env,
            [
                "--head",
                "--port",
                str(gcs),
                "--dashboard-host",
                "127.0.0.1",
                "--dashboard-port",
                str(dashboard),
                "--include-dashboard",
                "true",
                "--ray-client-server-port",
                str(client),
            ],
        )
        self._finish_start(node)
        current = Path(node.temp_dir) / "ray_current_cluster"
        self.address = (current.read_text().strip() if current.exists() else "") or (
            f"127.0.0.1:{gcs}"
        )
        self.dashboard_url = f"http://127.0.0.1:{dashboard}"
        deadline = time.monotonic() + START_TIMEOUT_S
        while not dashboard_answers(self.dashboard_url):
            if time.monotonic() > deadline:
                raise RayError(f"Ray dashboard at {self.dashboard_url}: no answer")
            time.sleep(0.2)
        logger.info("head up: %s, dashboard %s", self.address, self.dashboard_url)
        return node

    def add_node(
        self,
        name: str,
        num_cpus: int = 1,
        resources: dict[str, float] | None = None,
        env: dict[str, str] | None = None,
    ) -> RayNode:
        """Start a worker node (``ray start --address``) with ``num_cpus`` CPUs, the custom
        resource ``{name: 1}`` and ``resources``, and ``env`` added to its environment (its
        actors inherit it). Returns at once: :meth:`wait_for_nodes` waits for it."""
        if self.address is None:
            raise RayError("start the head first")
        return self._launch(
            name, num_cpus, {name: 1.0, **(resources or {})}, env or {}, ["--address", self.address]
        )

    def _launch(
        self,
        name: str,
        num_cpus: int,
        resources: dict[str, float],
        env: dict[str, str],
        role: list[str],
    ) -> RayNode:
        temp_dir = tempfile.mkdtemp(prefix="gf-n-", dir="/tmp")
        agent, agent_grpc, metrics, env_agent = free_ports(4)
        ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"
        command = [
            ray,
            "start",
            *role,
            "--node-ip-address",
            "127.0.0.1",
            "--num-cpus",
            str(num_cpus),
            "--resources",
            json.dumps(resources),
            "--temp-dir",
            temp_dir,
            "--object-store-memory",
            str(self.object_store_bytes),
            "--disable-usage-stats",
            "--dashboard-agent-listen-port",
            str(agent),
            "--dashboard-agent-grpc-port",
            str(agent_grpc),
            "--metrics-export-port",
            str(metrics),
            "--runtime-env-agent-port",
            str(env_agent),
            "--min-worker-port",
            "0",
            "--max-worker-port",
            "0",
        ]
        logger.info("starting Ray node %s (%d CPUs, %s)", name, num_cpus, resources)
        process = subprocess.Popen(
            command,
            env=self.env(env),
            start_new_session=True,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        node = RayNode(name, temp_dir, num_cpus, resources, process=process)
        self.nodes.append(node)
        return node

    def _finish_start(self, node: RayNode) -> None:
        """Wait for ``node``'s ``ray start`` to return.

        Raises:
            RayError: it failed or took longer than :data:`START_TIMEOUT_S`.
        """
        process, node.process = node.process, None
        if process is None:
            return
        try:
            output, _ = process.communicate(timeout=START_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            raise RayError(
                f"ray start ({node.name}): no answer in {START_TIMEOUT_S:.0f} s"
            ) from None
        if process.returncode != 0:
            tail = " | ".join(output.strip().splitlines()[-5:])
            raise RayError(f"ray start ({node.name}) failed (exit {process.returncode}): {tail}")

    def wait_for_nodes(self, timeout_s: float = START_TIMEOUT_S) -> dict[str, str]:
        """Wait until every started node is alive in Ray's state API; returns node id ->
        name (and sets each node's ``node_id``).

        Raises:
            RayError: a ``ray start`` failed, or not every node registered in ``timeout_s``.
        """
        for node in self.nodes:
            self._finish_start(node)
        deadline = time.monotonic() + timeout_s
        while True:
            found = {}
            for state in self.list_nodes():
                if state.state != "ALIVE":
                    continue
                for node in self.nodes:
                    if (node.name == "head") == state.is_head_node and (
                        node.name == "head" or node.name in state.resources_total
                    ):
                        found[node.name] = state.node_id
            live = [node for node in self.nodes if not node.stopped]
            if all(node.name in found for node in live):
                for node in live:
                    node.node_id = found[node.name]
                return {node.node_id: node.name for node in live if node.node_id}
            if time.monotonic() > deadline:
                missing = [node.name for node in live if node.name not in found]
                raise RayError(f"Ray nodes {missing}: not alive after {timeout_s:.0f} s")
            time.sleep(0.5)

    def state_client(self) -> Any:
        """Ray's state API client (``ray.util.state``) for the head, with the token."""
        from ray.util.state.api import StateApiClient  # lazy: imports much of Ray

        headers = {"Authorization": f"Bearer {self.token}", "Content-Type": "application/json"}
        return StateApiClient(address=self.dashboard_url, headers=headers)

    def list_nodes(self) -> list[Any]:
        """Ray's ``NodeState`` of every node the head knows (alive and dead)."""
        from ray.util.state.common import ListApiOptions, StateResource

        return self.state_client().list(
            StateResource.NODES, options=ListApiOptions(), raise_on_missing_output=False
        )

    def actors(self, class_name: str, state: str | None = "ALIVE") -> list[Any]:
        """Ray's ``ActorState`` of the actors of ``class_name`` (in ``state``; None: any),
        from the state API, as ``ray list actors`` shows them."""
        from ray.util.state.common import ListApiOptions, StateResource

        filters: list[tuple[str, str, str]] = [("class_name", "=", class_name)]
        if state is not None:
            filters.append(("state", "=", state))
        options = ListApiOptions(filters=filters, detail=True)
        return self.state_client().list(
            StateResource.ACTORS, options=options, raise_on_missing_output=False
        )

    def kill_node(self, node: RayNode) -> int:
        """SIGKILL every process of ``node`` at once (raylet, agents, workers and actors),
        as if its machine were lost; returns how many were killed."""
        pids = self._processes(node)
        for pid in pids:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        self._reap(node, pids, wait_s=10.0)
        logger.info("Ray node %s killed (%d processes)", node.name, len(pids))
        return len(pids)

    def stop_node(self, node: RayNode, grace_s: float = 3.0) -> None:
        """SIGTERM ``node``'s processes, SIGKILL what is left after ``grace_s``."""
        pids = self._processes(node)
        for pid in pids:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        while alive(pids) and time.monotonic() < deadline:
            time.sleep(0.1)
        for pid in alive(pids):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        self._reap(node, pids, wait_s=10.0)

    def shutdown(self) -> None:
        """Stop every node (worker nodes first, then the head and its drivers)."""
        for node in sorted(self.nodes, key=lambda n: n.name == "head"):
            if not node.stopped:
                self.stop_node(node)

    def _processes(self, node: RayNode) -> set[int]:
        """The live processes of ``node``: those naming its temp dir (its daemons; workers
        name their session directory) and everything below them (drivers of Ray jobs)."""
        if node.process is not None and node.process.poll() is None:
            node.process.kill()  # a ``ray start`` still running
        ours = set(pids_naming(node.temp_dir))
        return ours | descendants(ours)

    def _reap(self, node: RayNode, pids: set[int], wait_s: float) -> None:
        deadline = time.monotonic() + wait_s
        while (left := alive(pids)) and time.monotonic() < deadline:
            time.sleep(0.1)
        if left:
            logger.warning("Ray node %s: processes %s outlived SIGKILL", node.name, left)
        if node.process is not None:
            node.process.wait()
            node.process = None
        node.stopped = True
        shutil.rmtree(node.temp_dir, ignore_errors=True)
