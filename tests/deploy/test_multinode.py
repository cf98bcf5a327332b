"""A real multi-node Ray cluster on this machine, started with Ray's CLI as users start one:
``ray start --head --num-cpus 0`` and two ``ray start --address`` worker nodes (one CPU and a
custom resource each), token-authenticated; the service (``gaitforge serve``) pointed at the
head by ``GAITFORGE_RAY_ADDRESS``. A job submitted through the API runs one rollout actor on
each worker node (seen in each node's process tree, which does not lag as Ray's state API
does under load; the state API confirms at the end that the lost node's actor died), one
worker node is killed mid-job (every process of it, as a lost machine), and the job still
succeeds with a checkpoint whose scene carries the fidelity profile resolved on the driver
(the head): the worker nodes' saved profiles directory is empty, so an actor that resolved
the stage's saved profile name itself would fail there, and the profile is no built-in one.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from gaitforge.learner.checkpoint import load_checkpoint
from gaitforge.service.client.download import download
from gaitforge.service.client.http import GaitforgeClient
from gaitforge.service.client.round_trip import free_port, start_service, stop_service
from gaitforge.service.jobs.local_cluster import LocalCluster, RayNode
from gaitforge.service.jobs.procs import descendants, pids_naming
from gaitforge.workers.scenes.profiles import NAMED_PROFILES, FidelityProfile
from gaitforge.workers.scenes.saved_profiles import ENV_DIR, SavedProfile, save

logger = logging.getLogger(__name__)

SAVED = "stand-2d-mujoco-tol0.05"
PROFILE = FidelityProfile(integrator="implicitfast", timestep=0.01)
"""4 steps per 25 Hz control step; no built-in MuJoCo profile integrates like this"""
BUDGET = 256 * 32
"""env steps of the job: the kill comes after the first iteration (512 env steps here), which
leaves about 6 s of training on the surviving node here (12 s under load); the pool sees the
lost actor die within a second of the kill (within Ray's 3 s node health check at most)"""
API_TOKEN = "multinode-test-token"


@dataclass
class ClusterService:
    """The cluster, its worker nodes by name, and a client of the service on it."""

    cluster: LocalCluster
    workers: dict[str, RayNode]
    client: GaitforgeClient
    node_profiles: Path
    """the worker nodes' saved profiles directory (empty)"""


def _job() -> dict:
    """Two rollout actors (one CPU each: one per worker node), short fragments, the stage's
    fidelity a saved profile name that only the head's profiles directory holds."""
    return {
        "name": "multinode",
        "backend": "mujoco",
        "network": {"hidden": [32, 32]},
        "ppo": {"batch_env_steps": 256, "minibatch_size": 128, "epochs": 1},
        "workers": {"num_workers": 2, "envs_per_worker": 2, "fragment_length": 32},
        "checkpoint": {"every_iters": 4},
        "stages": [
            {
                "scene": "stand-2d",
                "scene_set": {"control_hz": 25, "fidelity": SAVED},
                "env_steps": BUDGET,
            }
        ],
    }


@pytest.fixture
def cluster_service(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[ClusterService]:
    """Head + node_a + node_b (Ray's CLI) and ``gaitforge serve`` on the head's address; all
    of it stopped at the end, whatever happened."""
    driver_dir, node_dir = tmp_path / "driver-profiles", tmp_path / "node-profiles"
    node_dir.mkdir()
    monkeypatch.setenv(ENV_DIR, str(driver_dir))
    save(
        SavedProfile(
            name=SAVED,
            scene="stand-2d",
            backend="mujoco",
            tolerance=0.05,
            profile=PROFILE,
            error=0.01,
            steps_per_s=1000.0,
        )
    )
    home = tmp_path / "home"
    cluster = LocalCluster()
    process = None
    try:
        cluster.start_head(num_cpus=0, env={ENV_DIR: str(driver_dir)})
        workers = {
            name: cluster.add_node(name, num_cpus=1, env={ENV_DIR: str(node_dir)})
            for name in ("node_a", "node_b")
        }  # they start while the service does (wait_for_nodes below)
        port = free_port()
        env = {k: v for k, v in os.environ.items() if not k.startswith(("GAITFORGE_", "RAY_"))}
        env.update(
            GAITFORGE_HOME=str(home),
            GAITFORGE_PORT=str(port),
            GAITFORGE_SERVER=f"http://127.0.0.1:{port}",
            GAITFORGE_POLL_INTERVAL_S="0.2",
            GAITFORGE_TOKENS=f"alice:{API_TOKEN}",
            GAITFORGE_RAY_ADDRESS=str(cluster.address),
            GAITFORGE_RAY_DASHBOARD=str(cluster.dashboard_url),
            RAY_AUTH_TOKEN=cluster.token,
            GAITFORGE_JOB_PYTHON=sys.executable,
            **{ENV_DIR: str(driver_dir)},
        )
        home.mkdir()
        process = start_service(env, home / "serve.log")
        cluster.wait_for_nodes()
        with GaitforgeClient(env["GAITFORGE_SERVER"], token=API_TOKEN) as client:
            yield ClusterService(cluster, workers, client, node_dir)
    finally:
        if process is not None:
            stop_service(process)
        cluster.shutdown()


def _rollout_actor_pids(node: RayNode) -> set[int]:
    """The rollout actors' processes among ``node``'s (its daemons and what they started)."""
    ours = set(pids_naming(node.temp_dir))
    found = set()
    for pid in ours | descendants(ours):
        try:
            if Path(f"/proc/{pid}/cmdline").read_bytes().startswith(b"ray::RolloutWorker"):
                found.add(pid)
        except OSError:
            continue
    return found


def _wait(
    client: GaitforgeClient, job_id: str, done: Callable[[dict], bool], timeout_s: float, what: str
) -> dict:
    """Poll the job's status until ``done``; fail naming its state, error and log tail."""
    deadline = time.monotonic() + timeout_s
    while True:
        status = client.status(job_id)
        if done(status):
            return status
        if status["state"] in ("failed", "cancelled") or time.monotonic() > deadline:
            log = client.logs(job_id)["text"][-2000:]
            pytest.fail(f"{job_id}: {what}: {status['state']} ({status.get('error')}); log: {log}")
        time.sleep(0.3)


@pytest.mark.timeout(240)  # about 20 s here; a hung cluster fails, not the suite
def test_a_job_spans_two_worker_nodes_and_survives_losing_one(
    cluster_service: ClusterService, tmp_path: Path
) -> None:
    assert PROFILE not in NAMED_PROFILES["mujoco"].values()
    cluster, client = cluster_service.cluster, cluster_service.client
    t0 = time.monotonic()
    job_id = client.submit(_job())["id"]

    deadline = time.monotonic() + 90
    while True:  # one live rollout actor on each worker node (its processes), trained on
        by_node = {
            name: _rollout_actor_pids(node) for name, node in cluster_service.workers.items()
        }
        status = client.status(job_id)
        if all(len(pids) == 1 for pids in by_node.values()) and (status["iteration"] or 0) >= 1:
            break
        if status["state"] not in ("queued", "running") or time.monotonic() > deadline:
            pytest.fail(f"actors by node {by_node}; job {status['state']}: {status.get('error')}")
        time.sleep(0.3)
    for (pid,) in by_node.values():  # they see the worker nodes' empty profiles directory
        environ = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
        assert f"{ENV_DIR}={cluster_service.node_profiles}".encode() in environ
    assert not any(cluster_service.node_profiles.iterdir())
    at_kill = client.status(job_id)
    assert at_kill["state"] == "running" and at_kill["phase"] in ("starting", "training"), at_kill
    logger.info(
        "actors up on both nodes after %.1f s, env steps %s",
        time.monotonic() - t0,
        at_kill["env_steps"],
    )

    lost = cluster_service.workers["node_a"]
    assert cluster.kill_node(lost) > 0
    final = _wait(client, job_id, lambda s: s["state"] == "succeeded", 120, "after the kill")
    logger.info("succeeded after %.1f s", time.monotonic() - t0)
    assert (at_kill["env_steps"] or 0) < BUDGET // 2, "the node went down mid-job"
    assert final["env_steps"] >= BUDGET and final["latest_checkpoint"], final
    deadline = time.monotonic() + 30  # Ray's state API lags under load
    while True:
        dead = {a.node_id for a in cluster.actors("RolloutWorker", state="DEAD")}
        if lost.node_id in dead or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    assert lost.node_id in dead, "the actor on the lost node died (Ray's state API)"
    log = client.logs(job_id)["text"]
    assert "rollout actor" in log and "died" in log, "the pool replaced the lost actor"

    (checkpoint,) = download(client, job_id, "checkpoints", "latest", tmp_path / "got")
    _, meta = load_checkpoint(checkpoint.path)
    assert meta.scene is not None and meta.env_steps >= BUDGET
    assert meta.scene["fidelity"] == {"mujoco": PROFILE.model_dump(mode="json")}
    assert meta.scene["fidelity_names"] == {"mujoco": SAVED}
