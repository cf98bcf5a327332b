"""Readers for the deploy files: YAML documents, the Dockerfile's instructions, env assignments
in shell commands and Kubernetes container specs."""

from __future__ import annotations

import re
import shlex
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
KUBERAY = DEPLOY / "kuberay"
API_PORT = 8765
RAY_PORTS = {6379: "GCS", 8265: "dashboard / jobs API", 10001: "Ray client"}
LOOPBACK = {"127.0.0.1", "localhost", "::1"}


def yaml_files() -> list[Path]:
    """Every YAML file under deploy/."""
    return sorted(p for p in DEPLOY.rglob("*") if p.suffix in (".yaml", ".yml"))


def load_docs(path: Path) -> list[dict[str, Any]]:
    """The YAML documents of ``path`` (empty ones skipped)."""
    return [doc for doc in yaml.safe_load_all(path.read_text()) if doc is not None]


def load_one(path: Path) -> dict[str, Any]:
    """The single YAML document of ``path``."""
    (doc,) = load_docs(path)
    return doc


def dockerfile_instructions(path: Path) -> list[tuple[str, str]]:
    """``[(INSTRUCTION, arguments)]`` of a Dockerfile: comments dropped, continuation lines
    joined (the parser directive ``# syntax=`` is a comment here)."""
    instructions: list[tuple[str, str]] = []
    pending = ""
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        words = (pending + line).split(None, 1)
        pending = ""
        instructions.append((words[0].upper(), words[1] if len(words) > 1 else ""))
    assert not pending, f"{path}: a continuation line at the end"
    return instructions


def exported_env(command: str) -> dict[str, str]:
    """``NAME=value`` words of ``export`` statements in a shell command line."""
    found: dict[str, str] = {}
    for statement in command.split(";"):
        words = shlex.split(statement.strip()) if statement.strip() else []
        if words[:1] == ["export"]:
            for word in words[1:]:
                name, sep, value = word.partition("=")
                if sep:
                    found[name] = value
    return found


def flag_values(command: str, flag: str) -> list[str]:
    """Values of ``--flag=value`` / ``--flag value`` in a command line."""
    return re.findall(rf"{re.escape(flag)}[= ]+([^\s;]+)", command)


def k8s_objects() -> list[dict[str, Any]]:
    """Every Kubernetes object of deploy/kuberay (the kustomization itself excluded)."""
    objects = []
    for path in sorted(KUBERAY.glob("*.yaml")):
        if path.name != "kustomization.yaml":
            objects += load_docs(path)
    return objects


def by_kind(objects: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [o for o in objects if o.get("kind") == kind]


def pod_specs(objects: list[dict[str, Any]]) -> Iterator[tuple[str, dict[str, Any]]]:
    """``(where, pod spec)`` of every pod template: Deployments, the RayCluster's head and
    worker groups."""
    for obj in objects:
        name = obj["metadata"]["name"]
        if obj["kind"] in ("Deployment", "StatefulSet", "DaemonSet", "Job"):
            yield f"{obj['kind']}/{name}", obj["spec"]["template"]["spec"]
        elif obj["kind"] == "RayCluster":
            yield f"RayCluster/{name} head", obj["spec"]["headGroupSpec"]["template"]["spec"]
            for group in obj["spec"].get("workerGroupSpecs", []):
                where = f"RayCluster/{name} workers {group['groupName']}"
                yield where, group["template"]["spec"]


def containers(objects: list[dict[str, Any]]) -> Iterator[tuple[str, dict[str, Any]]]:
    """``(where, container)`` of every container and init container of every pod template."""
    for where, spec in pod_specs(objects):
        for container in spec.get("initContainers", []) + spec["containers"]:
            yield f"{where} {container['name']}", container


def env_of(container: dict[str, Any]) -> dict[str, Any]:
    """name -> value (a string) or valueFrom (a mapping)."""
    return {e["name"]: e.get("value", e.get("valueFrom")) for e in container.get("env", [])}
