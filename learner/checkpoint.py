"""Checkpoints: one directory each, written atomically, loaded without unpickling.

Layout of ``<root>/ckpt-<env steps, 12 digits>/``:

    policy.safetensors       the policy's parameters (and buffers other than the normaliser)
    normalizer.safetensors   the observation normaliser's statistics (``norm.*``)
    meta.json                caller's metadata (job and scene spec, stage, env steps,
                             metrics, blending lineage, network config) + package versions
    manifest.json            sha256 of each file above

It is written into a temporary directory beside the target, each file fsynced, then
renamed into place: a reader sees a whole checkpoint or none. The last ``keep_last`` and the
best (by ``meta["metrics"][best_metric]``) are kept. Loading checks every hash and fails
loudly, naming the file and the reason.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tempfile
from importlib import metadata
from pathlib import Path

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

logger = logging.getLogger(__name__)

PREFIX = "ckpt-"
NORM_PREFIX = "norm."
FILES = ("policy.safetensors", "normalizer.safetensors", "meta.json")
PACKAGES = ("gaitforge", "torch", "mujoco", "opensim", "ray", "gymnasium")


class CheckpointError(RuntimeError):
    """A checkpoint is missing, damaged or inconsistent; the message names the file."""


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _versions() -> dict[str, str]:
    out = {}
    for package in PACKAGES:
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "not installed"
    return out


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def save_checkpoint(
    root: Path,
    env_steps: int,
    state: dict[str, torch.Tensor],
    meta: dict,
    keep_last: int = 3,
    best_metric: str | None = None,
) -> Path:
    """Write ``state`` (a policy ``state_dict``) and ``meta`` as a checkpoint under ``root``."""
    root.mkdir(parents=True, exist_ok=True)
    target = root / f"{PREFIX}{env_steps:012d}"
    tmp = Path(tempfile.mkdtemp(prefix=".tmp-", dir=root))
    try:
        tensors = {k: v.detach().contiguous().cpu() for k, v in state.items()}
        save_file({k: v for k, v in tensors.items() if not k.startswith(NORM_PREFIX)},
                  tmp / FILES[0])  # fmt: skip
        save_file({k: v for k, v in tensors.items() if k.startswith(NORM_PREFIX)}, tmp / FILES[1])
        full_meta = {**meta, "env_steps": env_steps, "versions": _versions()}
        (tmp / FILES[2]).write_text(json.dumps(full_meta, indent=2, sort_keys=True, default=str))
        manifest = {name: _sha256(tmp / name) for name in FILES}
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2))
        for name in (*FILES, "manifest.json"):
            _fsync(tmp / name)
        if target.exists():
            shutil.rmtree(target)
        tmp.rename(target)
        _fsync(root)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _prune(root, keep_last, best_metric)
    logger.info("checkpoint %s written", target)
    return target


def load_checkpoint(path: Path) -> tuple[dict[str, torch.Tensor], dict]:
    """The ``state_dict`` and metadata of the checkpoint directory ``path``.

    Raises:
        CheckpointError: naming the file that is missing, damaged or does not match.
    """
    manifest_path = path / "manifest.json"
    try:
        manifest = json.loads(manifest_path.read_text())
    except FileNotFoundError:
        raise CheckpointError(f"{manifest_path}: missing; {path} is not a checkpoint") from None
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"{manifest_path}: not valid JSON ({exc})") from None
    for name in FILES:
        file = path / name
        if not file.exists():
            raise CheckpointError(f"{file}: missing")
        if _sha256(file) != manifest.get(name):
            raise CheckpointError(f"{file}: sha256 does not match the manifest (damaged)")
    try:
        state = {**load_file(path / FILES[0]), **load_file(path / FILES[1])}
    except SafetensorError as exc:
        raise CheckpointError(f"{path}: unreadable safetensors ({exc})") from None
    return state, json.loads((path / FILES[2]).read_text())


def checkpoints(root: Path) -> list[Path]:
    """Complete checkpoints under ``root``, oldest first."""
    return sorted(p for p in root.glob(f"{PREFIX}*") if (p / "manifest.json").exists())


def latest_checkpoint(root: Path) -> Path | None:
    found = checkpoints(root)
    return found[-1] if found else None


def _prune(root: Path, keep_last: int, best_metric: str | None) -> None:
    found = checkpoints(root)
    keep = set(found[-keep_last:])
    if best_metric is not None:
        scored = [(p, json.loads((p / FILES[2]).read_text()).get("metrics", {})) for p in found]
        scored = [(p, m[best_metric]) for p, m in scored if best_metric in m]
        if scored:
            keep.add(max(scored, key=lambda pm: pm[1])[0])
    for path in found:
        if path not in keep:
            shutil.rmtree(path)
