"""deploy/: every YAML parses; the `ray up` configs pass Ray's own schema and preparation; Ray
runs with token authentication and keeps its ports inside the cluster; the Dockerfile builds a
non-root image with a health check; the image's helper scripts work.

KubeRay's manifests: test_deploy_kuberay.py."""

from __future__ import annotations

import http.server
import json
import os
import re
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import ray.autoscaler
from deploy_support import (
    API_PORT,
    DEPLOY,
    LOOPBACK,
    ROOT,
    dockerfile_instructions,
    exported_env,
    flag_values,
    load_docs,
    load_one,
    yaml_files,
)
from gaitforge.service.settings import ServiceSettings

RAY_UP_FILES = [DEPLOY / "cluster.yaml", DEPLOY / "cluster-onprem.yaml"]
RAY_UP_KEYS = {
    "cluster_name",
    "max_workers",
    "provider",
    "head_start_ray_commands",
    "worker_start_ray_commands",
}
COMMAND_KEYS = (
    "initialization_commands",
    "setup_commands",
    "head_setup_commands",
    "worker_setup_commands",
    "head_start_ray_commands",
    "worker_start_ray_commands",
)
DOCKERFILE = DEPLOY / "Dockerfile"
EXTRA_GAITFORGE_ENV = {
    "GAITFORGE_RAY_DASHBOARD",
    "GAITFORGE_JOB_PYTHON",
    "GAITFORGE_HEALTHCHECK",
    "GAITFORGE_START_WAIT_S",
}
"""GAITFORGE_* variables read outside ServiceSettings (runner, image scripts)"""


def test_every_yaml_file_parses_into_mappings() -> None:
    files = yaml_files()
    assert {p.name for p in files} >= {
        "cluster.yaml",
        "cluster-onprem.yaml",
        "raycluster.yaml",
        "api.yaml",
        "kustomization.yaml",
    }
    for path in files:
        docs = load_docs(path)
        assert docs, f"{path}: no document"
        assert all(isinstance(doc, dict) for doc in docs), f"{path}: a document is no mapping"


@pytest.mark.parametrize("path", RAY_UP_FILES, ids=lambda p: p.name)
def test_ray_up_config_passes_rays_schema_and_preparation(path: Path) -> None:
    from ray.autoscaler._private.util import prepare_config, validate_config

    config = load_one(path)
    assert config.keys() >= RAY_UP_KEYS, f"{path.name}: missing {RAY_UP_KEYS - config.keys()}"
    schema_path = Path(ray.autoscaler.__file__).parent / "ray-schema.json"
    jsonschema.validate(config, json.loads(schema_path.read_text()))
    prepared = prepare_config(config)  # what `ray up` does before it launches anything
    validate_config(prepared)
    assert prepared["head_node_type"] in prepared["available_node_types"]


def test_cloud_config_has_head_and_autoscaling_cpu_workers() -> None:
    config = load_one(DEPLOY / "cluster.yaml")
    types = config["available_node_types"]
    assert config["head_node_type"] in types
    workers = [t for name, t in types.items() if name != config["head_node_type"]]
    assert workers, "no worker node type"
    for worker in workers:
        assert 0 <= worker["min_workers"] < worker["max_workers"] <= config["max_workers"]
    assert config["docker"]["image"], "no image"


def test_onprem_config_names_its_machines_and_no_node_types() -> None:
    config = load_one(DEPLOY / "cluster-onprem.yaml")
    provider = config["provider"]
    assert provider["type"] == "local"
    assert provider["head_ip"] and provider["worker_ips"]
    assert provider["head_ip"] not in provider["worker_ips"]
    assert "available_node_types" not in config and "head_node_type" not in config


def ray_up_commands(config: dict[str, Any]) -> Iterator[str]:
    for key in COMMAND_KEYS:
        yield from config.get(key) or []


@pytest.mark.parametrize("path", RAY_UP_FILES, ids=lambda p: p.name)
def test_ray_up_starts_ray_with_token_auth_and_a_loopback_dashboard(path: Path) -> None:
    config = load_one(path)
    starts = [c for c in ray_up_commands(config) if "ray start" in c]
    assert any("--head" in c for c in starts) and any("--address" in c for c in starts)
    for command in starts:
        assert exported_env(command).get("RAY_AUTH_MODE") == "token", command
        for host in flag_values(command, "--dashboard-host"):
            assert host in LOOPBACK, f"{path.name}: dashboard on {host}: {command}"
    assert "-e RAY_AUTH_MODE=token" in config["docker"]["run_options"]
    # the token reaches every node (file_mounts go to the head and from it to the workers)
    assert "~/.ray/auth_token" in config["file_mounts"]


@pytest.mark.parametrize("path", RAY_UP_FILES, ids=lambda p: p.name)
def test_ray_up_opens_only_the_api_port(path: Path) -> None:
    config = load_one(path)
    docker = config["docker"]
    for option in [
        *docker.get("run_options", []),
        *docker.get("head_run_options", []),
        *docker.get("worker_run_options", []),
    ]:
        assert not re.match(r"(-p|--publish)\b", option), f"{path.name}: publishes {option}"
    rules = config["provider"].get("security_group", {}).get("IpPermissions", [])
    for rule in rules:
        assert rule["FromPort"] == rule["ToPort"] == API_PORT, f"{path.name}: opens {rule}"


@pytest.mark.parametrize("path", RAY_UP_FILES, ids=lambda p: p.name)
def test_ray_up_service_settings_are_valid_and_shared(path: Path) -> None:
    config = load_one(path)
    (command,) = [c for c in config["head_start_ray_commands"] if "gaitforge-start-service" in c]
    env = exported_env(command)
    assert env["RAY_AUTH_MODE"] == "token"
    assert env["GAITFORGE_HOST"] == "0.0.0.0" and int(env["GAITFORGE_PORT"]) == API_PORT
    settings = service_settings(env)
    assert settings.tokens_file is not None, "beyond loopback the service needs tokens"
    token_target = str(settings.tokens_file).replace("$HOME", "~")
    assert token_target in config["file_mounts"], "the API tokens are not copied to the head"
    mounted = [o.split(":")[1] for o in config["docker"]["head_run_options"] if o.startswith("-v")]
    for directory in (settings.home, settings.artifacts):
        assert any(str(directory).startswith(m) for m in mounted), f"{directory}: not on a volume"
    assert env["GAITFORGE_RAY_DASHBOARD"].split("//")[1].split(":")[0] in LOOPBACK


def service_settings(env: dict[str, str]) -> ServiceSettings:
    """The service's settings from ``GAITFORGE_*`` assignments (each must be a setting, or one
    of the variables read elsewhere), validated."""
    fields: dict[str, str] = {}
    for name, value in env.items():
        if name.startswith("GAITFORGE_") and name not in EXTRA_GAITFORGE_ENV:
            field = name.removeprefix("GAITFORGE_").lower()
            assert field in ServiceSettings.model_fields, f"{name}: no such setting"
            fields[field] = value
    return ServiceSettings(**fields)


def test_dockerfile_builds_a_non_root_cpu_image_with_a_health_check() -> None:
    steps = dockerfile_instructions(DOCKERFILE)
    kinds = [kind for kind, _ in steps]
    assert kinds[0] in ("ARG", "FROM") and "FROM" in kinds
    users = [args.split()[0] for kind, args in steps if kind == "USER"]
    assert users and users[-1].split(":")[0].isdigit(), "USER numeric (runAsNonRoot checks it)"
    assert int(users[-1].split(":")[0]) != 0, "the image runs as root"
    env = " ".join(args for kind, args in steps if kind == "ENV")
    assert re.search(r"\bHOME=/home/", env), "HOME in the image's env (ray up places files there)"
    assert kinds.index("USER") < kinds.index("CMD")
    (health,) = [args for kind, args in steps if kind == "HEALTHCHECK"]
    assert "gaitforge-healthcheck" in health and not health.upper().startswith("NONE")
    runs = [args for kind, args in steps if kind == "RUN"]
    (torch,) = [r for r in runs if "torch==" in r]
    pins = re.findall(r"TORCH_VERSION=(\S+)", " ".join(a for k, a in steps if k == "ARG"))
    make_pin = re.search(r"torch==(\S+)", (ROOT / "Makefile").read_text())
    assert make_pin and pins == [make_pin.group(1)], "the image's torch is not make's"
    assert "--index-url https://download.pytorch.org/whl/cpu" in torch
    (project,) = [r for r in runs if re.search(r"pip install .*\s/src\b", r)]
    assert "--mount=type=bind,target=/src" in project
    exposed = {args for kind, args in steps if kind == "EXPOSE"}
    assert exposed == {str(API_PORT)}, "only the API port is exposed"


def test_dockerignore_sends_only_the_sources() -> None:
    lines = (DEPLOY / "Dockerfile.dockerignore").read_text().splitlines()
    patterns = [line.strip() for line in lines if line.strip() and not line.startswith("#")]
    assert patterns[0] == "*", "an allow-list: everything else (.venv, runs, secrets) stays out"
    allowed = {p[1:] for p in patterns if p.startswith("!")}
    for needed in ("pyproject.toml", "README.md", "learner", "service", "workers"):
        assert needed in allowed
    for script in re.findall(r"/src/(deploy/\S+)", DOCKERFILE.read_text()):
        assert script in allowed and (ROOT / script).is_file(), script


def test_docker_build_check() -> None:
    docker = shutil.which("docker")
    if docker is None:
        pytest.skip("docker is not installed here")
    probe = subprocess.run([docker, "buildx", "version"], capture_output=True, timeout=10)
    if probe.returncode != 0:
        pytest.skip("docker build --check needs BuildKit (buildx) and a daemon: neither is here")
    result = subprocess.run(
        [docker, "build", "--check", "-f", str(DOCKERFILE), str(ROOT)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    if "Cannot connect to the Docker daemon" in result.stderr:
        pytest.skip("docker build --check needs a Docker daemon: none runs here")
    assert result.returncode == 0, result.stderr


def test_start_service_script_is_valid_bash() -> None:
    script = DEPLOY / "start-service.sh"
    assert os.access(script, os.X_OK)
    result = subprocess.run(["bash", "-n", str(script)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


class Healthz(http.server.BaseHTTPRequestHandler):
    status = 200

    def do_GET(self) -> None:
        self.send_response(self.status if self.path == "/healthz" else 404)
        self.end_headers()

    def log_message(self, *args: object) -> None:
        pass


def healthcheck(env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    script = DEPLOY / "healthcheck.py"
    return subprocess.run(
        [sys.executable, str(script)],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=30,
    )


def test_healthcheck_follows_the_api() -> None:
    server = http.server.HTTPServer(("127.0.0.1", 0), Healthz)
    port = str(server.server_address[1])
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        assert healthcheck({"GAITFORGE_PORT": port}).returncode == 0
        Healthz.status = 503
        failed = healthcheck({"GAITFORGE_PORT": port, "GAITFORGE_HEALTHCHECK": "api"})
        assert failed.returncode == 1 and "HTTP 503" in failed.stderr
    finally:
        Healthz.status = 200
        server.shutdown()
        server.server_close()
    down = healthcheck({"GAITFORGE_PORT": port})
    assert down.returncode == 1 and "unhealthy" in down.stderr
    assert healthcheck({"GAITFORGE_HEALTHCHECK": "none"}).returncode == 0
    bad = healthcheck({"GAITFORGE_HEALTHCHECK": "web"})
    assert bad.returncode == 1 and "expected api, ray or none" in bad.stderr


def test_healthcheck_finds_a_raylet(tmp_path: Path) -> None:
    sys.path.insert(0, str(DEPLOY))
    try:
        import healthcheck as module
    finally:
        sys.path.remove(str(DEPLOY))
    (tmp_path / "self").mkdir()
    (tmp_path / "12").mkdir()
    (tmp_path / "12" / "cmdline").write_bytes(b"python\0-m\0ray.raylet_helper\0")
    assert module.raylet_running(tmp_path) == "no raylet process runs here"
    (tmp_path / "34").mkdir()
    (tmp_path / "34" / "cmdline").write_bytes(b"/x/ray/core/src/ray/raylet/raylet\0--a=b\0")
    assert module.raylet_running(tmp_path) is None
