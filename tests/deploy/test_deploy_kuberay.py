"""deploy/kuberay: a RayCluster with token authentication everywhere, the gaitforge API pointed
at its head, one shared artifact volume at one path on every pod, nothing of Ray exposed beyond
the cluster; the kustomization renders (``kubectl kustomize``, offline) and kubectl reads every
object it renders."""

from __future__ import annotations

import shutil
import subprocess
from typing import Any

import pytest
import yaml
from deploy_support import (
    API_PORT,
    DEPLOY,
    KUBERAY,
    RAY_PORTS,
    by_kind,
    containers,
    dockerfile_instructions,
    env_of,
    k8s_objects,
    load_one,
    pod_specs,
)
from gaitforge.service.settings import ServiceSettings

RAY_SECRET = "gaitforge-ray-token"


@pytest.fixture(scope="module")
def objects() -> list[dict[str, Any]]:
    return k8s_objects()


def raycluster(objects: list[dict[str, Any]]) -> dict[str, Any]:
    (cluster,) = by_kind(objects, "RayCluster")
    return cluster


def api_container(objects: list[dict[str, Any]]) -> dict[str, Any]:
    (deployment,) = by_kind(objects, "Deployment")
    (container,) = deployment["spec"]["template"]["spec"]["containers"]
    return container


def assert_token_auth(where: str, env: dict[str, Any]) -> None:
    assert env.get("RAY_AUTH_MODE") == "token", f"{where}: RAY_AUTH_MODE is not token"
    ref = (env.get("RAY_AUTH_TOKEN") or {}).get("secretKeyRef", {})
    assert ref.get("name") == RAY_SECRET and ref.get("key"), f"{where}: no token from the Secret"


def test_every_ray_container_runs_with_token_auth(objects: list[dict[str, Any]]) -> None:
    cluster = raycluster(objects)
    assert cluster["apiVersion"] == "ray.io/v1"
    for where, container in containers(objects):
        assert_token_auth(where, env_of(container))
    assert cluster["spec"]["enableInTreeAutoscaling"] is True
    autoscaler = cluster["spec"]["autoscalerOptions"]
    assert_token_auth(
        "autoscaler", {e["name"]: e.get("value", e.get("valueFrom")) for e in autoscaler["env"]}
    )


def test_head_and_autoscaling_cpu_workers(objects: list[dict[str, Any]]) -> None:
    spec = raycluster(objects)["spec"]
    (_, dockerfile_ray) = next(
        (k, a) for k, a in dockerfile_instructions(DEPLOY / "Dockerfile") if "RAY_VERSION=" in a
    )
    assert spec["rayVersion"] == dockerfile_ray.split("=", 1)[1], "image and rayVersion differ"
    (group,) = spec["workerGroupSpecs"]
    assert 0 <= group["minReplicas"] <= group["replicas"] <= group["maxReplicas"]
    assert group["maxReplicas"] > group["minReplicas"]


def test_nothing_of_ray_is_exposed_outside(objects: list[dict[str, Any]]) -> None:
    head = raycluster(objects)["spec"]["headGroupSpec"]
    assert head.get("serviceType", "ClusterIP") == "ClusterIP"
    for service in by_kind(objects, "Service"):
        assert service["spec"].get("type", "ClusterIP") == "ClusterIP", service["metadata"]
        ports = {p.get("targetPort") for p in service["spec"]["ports"]} | {
            p["port"] for p in service["spec"]["ports"]
        }
        assert not ports & RAY_PORTS.keys(), f"{service['metadata']['name']} serves Ray ports"
    assert not by_kind(objects, "Ingress"), "an Ingress is the user's to add, for the API only"
    for where, spec in pod_specs(objects):
        assert not spec.get("hostNetwork"), f"{where}: hostNetwork"
    for where, container in containers(objects):
        for port in container.get("ports", []):
            assert "hostPort" not in port, f"{where}: hostPort {port}"


def test_head_dashboard_on_all_interfaces_only_behind_a_network_policy(
    objects: list[dict[str, Any]],
) -> None:
    cluster = raycluster(objects)
    host = cluster["spec"]["headGroupSpec"]["rayStartParams"].get("dashboard-host", "0.0.0.0")
    if host in ("127.0.0.1", "localhost"):
        return
    selector = {"ray.io/cluster": cluster["metadata"]["name"]}
    policies = [
        p
        for p in by_kind(objects, "NetworkPolicy")
        if p["spec"]["podSelector"].get("matchLabels") == selector
    ]
    assert policies, "the head's dashboard listens on all interfaces with no NetworkPolicy"
    api_labels = by_kind(objects, "Deployment")[0]["spec"]["template"]["metadata"]["labels"]
    for policy in policies:
        assert "Ingress" in policy["spec"]["policyTypes"]
        for rule in policy["spec"]["ingress"]:
            peers = rule.get("from")
            assert peers, f"{policy['metadata']['name']}: a rule admits anyone"
            for peer in peers:
                assert "ipBlock" not in peer and "namespaceSelector" not in peer, peer
                labels = peer["podSelector"]["matchLabels"]
                assert labels == selector or labels.items() <= api_labels.items(), peer
            if peers[0]["podSelector"]["matchLabels"] != selector:
                assert {p["port"] for p in rule["ports"]} == {8265}, "the API needs the jobs API"


def test_artifacts_on_one_shared_volume_at_one_path(objects: list[dict[str, Any]]) -> None:
    claims = {c["metadata"]["name"]: c for c in by_kind(objects, "PersistentVolumeClaim")}
    api_env = env_of(api_container(objects))
    root = api_env["GAITFORGE_ARTIFACT_ROOT"]
    paths = {}
    for where, spec in pod_specs(objects):
        volumes = {v["name"]: v for v in spec.get("volumes", [])}
        for container in spec["containers"]:
            for mount in container.get("volumeMounts", []):
                claim = volumes[mount["name"]].get("persistentVolumeClaim", {}).get("claimName")
                if claim and "ReadWriteMany" in claims[claim]["spec"]["accessModes"]:
                    paths[f"{where} {container['name']}"] = mount["mountPath"]
    assert len(paths) == len(list(pod_specs(objects))), f"not on every pod: {paths}"
    assert set(paths.values()) == {root}, f"the artifact root differs: {paths} vs {root}"
    state = [c for c in claims.values() if c["spec"]["accessModes"] == ["ReadWriteOnce"]]
    assert state, "the service's database needs a volume of its own (SQLite: not on a share)"


def test_api_points_at_the_head_with_valid_settings(objects: list[dict[str, Any]]) -> None:
    name = raycluster(objects)["metadata"]["name"]
    container = api_container(objects)
    env = env_of(container)
    assert env["GAITFORGE_RAY_ADDRESS"] == f"{name}-head-svc:6379"
    assert env["GAITFORGE_RAY_DASHBOARD"] == f"http://{name}-head-svc:8265"
    fields = {
        k.removeprefix("GAITFORGE_").lower(): v
        for k, v in env.items()
        if k.startswith("GAITFORGE_")
        and k not in ("GAITFORGE_RAY_DASHBOARD", "GAITFORGE_JOB_PYTHON")
    }
    assert fields.keys() <= ServiceSettings.model_fields.keys(), fields.keys()
    settings = ServiceSettings(**fields)
    assert settings.tokens_file is not None, "beyond loopback the service needs tokens"
    mounts = {m["mountPath"]: m for m in container["volumeMounts"]}
    (deployment,) = by_kind(objects, "Deployment")
    volumes = {v["name"]: v for v in deployment["spec"]["template"]["spec"]["volumes"]}
    token_dir = str(settings.tokens_file.parent)
    assert mounts[token_dir].get("readOnly") is True
    assert "secret" in volumes[mounts[token_dir]["name"]], "API tokens not from a Secret"
    assert deployment["spec"]["replicas"] == 1 and deployment["spec"]["strategy"]["type"] == (
        "Recreate"
    )


def test_api_probes_healthz_and_runs_non_root(objects: list[dict[str, Any]]) -> None:
    container = api_container(objects)
    (port,) = container["ports"]
    assert port["containerPort"] == API_PORT
    for probe in ("livenessProbe", "readinessProbe"):
        get = container[probe]["httpGet"]
        assert get["path"] == "/healthz" and get["port"] in (port["name"], API_PORT), probe
    (user,) = [a for k, a in dockerfile_instructions(DEPLOY / "Dockerfile") if k == "USER"]
    for where, spec in pod_specs(objects):
        assert spec["securityContext"]["runAsNonRoot"] is True, where
        assert str(spec["securityContext"]["runAsUser"]) == user.split(":")[0], where
    (service,) = by_kind(objects, "Service")
    (service_port,) = service["spec"]["ports"]
    assert service_port["targetPort"] in (port["name"], API_PORT)


def test_kustomization_lists_every_manifest() -> None:
    kustomization = load_one(KUBERAY / "kustomization.yaml")
    listed = set(kustomization["resources"])
    present = {p.name for p in KUBERAY.glob("*.yaml")} - {"kustomization.yaml"}
    assert listed == present
    assert [i["name"] for i in kustomization["images"]] == ["gaitforge"]


def test_kubectl_renders_and_reads_the_manifests() -> None:
    kubectl = shutil.which("kubectl")
    if kubectl is None:
        pytest.skip("kubectl is not installed here")
    rendered = subprocess.run(
        [kubectl, "kustomize", str(KUBERAY)], capture_output=True, text=True, timeout=60
    )
    assert rendered.returncode == 0, rendered.stderr
    docs = [d for d in yaml.safe_load_all(rendered.stdout) if d]
    kustomization = load_one(KUBERAY / "kustomization.yaml")
    (image,) = kustomization["images"]
    wanted = f"{image['newName']}:{image['newTag']}"
    assert {c["image"] for _, c in containers(docs)} == {wanted}
    assert all(
        d["metadata"].get("namespace") == "gaitforge" for d in docs if d["kind"] != "Namespace"
    )
    # `kubectl apply --dry-run=client` needs an API server (discovery); `label --local` parses
    # every object the same way without one.
    read = subprocess.run(
        [kubectl, "label", "--local", "--dry-run=client", "-o", "name", "-f", "-", "checked=1"],
        input=rendered.stdout,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert read.returncode == 0, read.stderr
    names = set(read.stdout.split())
    for doc in docs:
        group, _, _ = doc["apiVersion"].rpartition("/")  # "" for the core group ("v1")
        kind = doc["kind"].lower() + (f".{group}" if group else "")
        assert f"{kind}/{doc['metadata']['name']}" in names, (kind, names)
