"""The pool on a local multi-node Ray cluster (a head and two worker nodes on this machine):
actors spread over the nodes, a lost node costs at most its in-flight fragments, and the
pool fills back up when a node returns."""

from __future__ import annotations

import functools
import time
from collections import Counter
from collections.abc import Iterator

import pytest
import ray
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import WorkerPool
from gaitforge.workers.scenes import load_scene
from ray.cluster_utils import Cluster

POLICY = functools.partial(UniformExcitationPolicy, 6)  # elbow-reach


@pytest.fixture()
def cluster() -> Iterator[Cluster]:
    """A head with no CPUs (the learner's node) and two 1-CPU worker nodes."""
    local = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    local.add_node(num_cpus=1)
    local.add_node(num_cpus=1)
    ray.init(address=local.address, logging_level="ERROR")
    local.wait_for_nodes()
    yield local
    ray.shutdown()
    local.shutdown()


def _fragments_by_worker(pool: WorkerPool, seconds: float) -> Counter[int]:
    """Fragments each worker id delivered within ``seconds``."""
    seen: Counter[int] = Counter()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        seen[pool.next_fragment(timeout_s=seconds)[0].worker] += 1
    return seen


def test_actors_spread_and_survive_a_node_leaving_and_returning(cluster: Cluster) -> None:
    scene = load_scene("elbow-reach").resolved()
    pool = WorkerPool(scene, POLICY, num_workers=2, fragment_length=16)
    try:
        nodes = pool.node_ids()
        assert len(set(nodes)) == 2, "one actor per worker node"
        assert set(_fragments_by_worker(pool, 5)) == {0, 1}

        leaving = next(n for n in cluster.worker_nodes if n.node_id == nodes[1])
        cluster.remove_node(leaving)
        after = _fragments_by_worker(pool, 10)
        assert after[0] > 0, "the other node's actor carries on"
        # fragments worker 1 finished before its node went may still arrive, no new ones
        assert after[1] <= pool.queue_depth and set(after) <= {0, 1}
        assert pool.stats.actor_deaths == 1, "only the lost node's queued requests are lost"
        assert 1 <= pool.stats.reissued <= pool.queue_depth

        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        deadline = time.monotonic() + 90
        seen: set[int] = set()
        while len(seen) < 2 and time.monotonic() < deadline:
            seen.add(pool.next_fragment(timeout_s=90)[0].worker)
        assert seen == {0, 2}, "the replacement starts on the returning node"
        assert len(set(pool.node_ids())) == 2
    finally:
        pool.close()
