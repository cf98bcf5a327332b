"""Scenes resolve on the driver: on a local multi-node cluster (a head and two worker nodes
on this machine) whose worker nodes see an empty profiles directory, a job with
``fidelity: auto`` steps there with the profile saved on the driver."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest
import ray
import yaml
from gaitforge.learner.job import load_job
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import WorkerPool
from gaitforge.workers.scenes import saved_profiles, scene_fields
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.scenes.saved_profiles import ENV_DIR, SavedProfile
from ray.cluster_utils import Cluster

POLICY = functools.partial(UniformExcitationPolicy, 6)  # elbow-reach
PROFILE = FidelityProfile(integrator="rk4", timestep=0.0025)
"""Distinctive: no built-in profile integrates like this (4 steps per 50 Hz control step)."""
SAVED = "elbow-reach-mujoco-tol0.05"


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
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    driver_dir, node_dir = tmp_path / "driver-profiles", tmp_path / "node-profiles"
    node_dir.mkdir()
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

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    try:
        for _ in range(2):  # worker nodes: their processes see the empty directory
            cluster.add_node(num_cpus=1, env_vars={ENV_DIR: str(node_dir)})
        ray.init(address=cluster.address, logging_level="ERROR")
        cluster.wait_for_nodes()
        where, files, outcome = ray.get(_node_view.remote(unresolved), timeout=120)
        assert (where, files) == (str(node_dir), [])
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
    finally:
        ray.shutdown()
        cluster.shutdown()
