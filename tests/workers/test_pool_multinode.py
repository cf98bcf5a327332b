"""The pool on a local multi-node Ray cluster (a head and two worker nodes on this machine,
shared by this module's tests; the worker nodes' processes see an empty profiles directory):
scenes resolve on the driver, so a job with ``fidelity: auto`` steps on the worker nodes with
the profile saved on the driver; actors spread over the nodes, a lost node costs at most its
in-flight fragments, and the pool fills back up when a node returns."""

from __future__ import annotations

import functools
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import ray
import yaml
from gaitforge.learner.job import load_job
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import WorkerPool
from gaitforge.workers.scenes import load_scene, saved_profiles, scene_fields
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.scenes.saved_profiles import ENV_DIR, SavedProfile
from ray.cluster_utils import Cluster

POLICY = functools.partial(UniformExcitationPolicy, 6)  # elbow-reach
PROFILE = FidelityProfile(integrator="rk4", timestep=0.0025)
"""Distinctive: no built-in profile integrates like this (4 steps per 50 Hz control step)."""
SAVED = "elbow-reach-mujoco-tol0.05"


@dataclass
class LocalNodes:
    cluster: Cluster
    node_profiles: Path
    """the worker nodes' saved profiles directory (empty)"""


@pytest.fixture(scope="module")
def nodes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LocalNodes]:
    """A head with no CPUs (the learner's node) and two 1-CPU worker nodes whose processes
    see an empty profiles directory."""
    node_dir = tmp_path_factory.mktemp("node-profiles")
    local = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    try:
        for _ in range(2):
            local.add_node(num_cpus=1, env_vars={ENV_DIR: str(node_dir)})
        ray.init(address=local.address, logging_level="ERROR")
        local.wait_for_nodes()
        yield LocalNodes(local, node_dir)
    finally:
        ray.shutdown()
        local.shutdown()


@ray.remote(num_cpus=1)
def _node_view(raw_scene: dict) -> tuple[str, list[str], str]:
    """On a worker node: its profiles directory, the files in it, and what validating the
    unresolved scene there gives."""
    from gaitforge.workers.scenes import Scene
    from gaitforge.workers.scenes.saved_profiles import profiles_dir
    from pydantic import ValidationError

    directory = profiles_dir()
    files = sorted(p.name for p in directory.iterdir()) if directory.exists() else []
    try:
        Scene.model_validate(raw_scene)
        outcome = "loaded"
    except ValidationError as exc:
        outcome = str(exc)
    return str(directory), files, outcome


def _job(tmp_path: Path) -> Path:
    """A one-stage job on elbow-reach with ``fidelity: auto`` (tolerance 0.05 rad)."""
    raw = scene_fields("elbow-reach")
    raw.update(fidelity="auto", fidelity_tolerance=0.05)
    (tmp_path / "elbow-auto.yaml").write_text(yaml.safe_dump(raw))
    job = {"name": "auto", "stages": [{"scene": "elbow-auto.yaml", "env_steps": 1000}]}
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(job))
    return path


def test_auto_fidelity_steps_on_worker_nodes_with_the_drivers_profile(
    nodes: LocalNodes, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    driver_dir = tmp_path / "driver-profiles"
    monkeypatch.setenv(ENV_DIR, str(driver_dir))
    saved_profiles.save(
        SavedProfile(
            name=SAVED,
            scene="elbow-reach",
            backend="mujoco",
            tolerance=0.05,
            profile=PROFILE,
            error=0.01,
            steps_per_s=1000.0,
        )
    )
    job, scenes, _ = load_job(_job(tmp_path))
    scene = scenes[0]
    assert scene.is_resolved
    assert scene.fidelity == {"mujoco": PROFILE}
    assert scene.fidelity_names == {"mujoco": f"auto: {SAVED}"}
    unresolved = scene.model_dump(mode="json") | {"fidelity": "auto", "fidelity_names": {}}

    where, files, outcome = ray.get(_node_view.remote(unresolved), timeout=120)
    assert (where, files) == (str(nodes.node_profiles), [])
    assert "no saved profile for scene 'elbow-reach'" in outcome  # auto fails there

    pool = WorkerPool(scene, POLICY, backend=job.backend, num_workers=2, fragment_length=8)
    try:
        assert len(set(pool.node_ids())) == 2, "one actor per worker node"
        assert pool.sim_profiles() == [PROFILE, PROFILE]
        for _ in range(4):
            pool.next_fragment(timeout_s=120)
        assert pool.stats.env_steps == 4 * 8 * 4 and pool.stats.actor_deaths == 0
    finally:
        pool.close()


def _fragments_by_worker(
    pool: WorkerPool, done: Callable[[Counter[int]], bool], timeout_s: float = 90
) -> Counter[int]:
    """Fragments each worker id delivered until ``done(counts)`` (``timeout_s`` at most)."""
    seen: Counter[int] = Counter()
    deadline = time.monotonic() + timeout_s
    while not done(seen) and time.monotonic() < deadline:
        seen[pool.next_fragment(timeout_s=timeout_s)[0].worker] += 1
    return seen


def test_actors_spread_and_survive_a_node_leaving_and_returning(nodes: LocalNodes) -> None:
    """It removes a worker node and adds another like it (the module's others need two)."""
    cluster = nodes.cluster
    scene = load_scene("elbow-reach").resolved()
    pool = WorkerPool(scene, POLICY, num_workers=2, fragment_length=16)
    try:
        node_ids = pool.node_ids()
        assert len(set(node_ids)) == 2, "one actor per worker node"
        assert set(_fragments_by_worker(pool, lambda seen: len(seen) == 2)) == {0, 1}

        leaving = next(n for n in cluster.worker_nodes if n.node_id == node_ids[1])
        cluster.remove_node(leaving)
        # until the pool has seen the death and the other node's actor has delivered 8 more
        after = _fragments_by_worker(
            pool, lambda seen: pool.stats.actor_deaths >= 1 and seen[0] >= 8
        )
        assert after[0] >= 8, "the other node's actor carries on"
        # fragments worker 1 finished before its node went may still arrive, no new ones
        assert after[1] <= pool.queue_depth and set(after) <= {0, 1}
        assert pool.stats.actor_deaths == 1, "only the lost node's queued requests are lost"
        assert 1 <= pool.stats.reissued <= pool.queue_depth

        cluster.add_node(num_cpus=1, env_vars={ENV_DIR: str(nodes.node_profiles)})
        cluster.wait_for_nodes()
        seen = set(_fragments_by_worker(pool, lambda seen: len(seen) == 2))
        assert seen == {0, 2}, "the replacement starts on the returning node"
        assert len(set(pool.node_ids())) == 2
        assert pool.stats.actor_deaths == 1
    finally:
        pool.close()
