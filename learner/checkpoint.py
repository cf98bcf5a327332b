"""Checkpoints: one directory each, written atomically, loaded without unpickling.

Layout of ``<root>/ckpt-<env steps, 12 digits>/``:

    policy.safetensors       the policy's parameters (and buffers other than the normaliser)
    normalizer.safetensors   the observation normaliser's statistics (``norm.*``)
    optimizer.safetensors    the optimizer's state (Adam moments), when given; its
                             param groups go into meta.json under "optimizer_param_groups"
    meta.json                ``learner.checkpoint_meta.CheckpointMeta`` (job and scene spec,
                             stage, env steps, metrics, blending lineage, network config,
                             package versions, schema version)
    manifest.json            sha256 of each file above

It is written into a temporary directory beside the target, each file fsynced, then
renamed into place: a reader sees a whole checkpoint or none. The last ``keep_last`` and the
best (:func:`select_checkpoint`) are kept. Loading checks every hash and fails loudly, naming
the file and the reason.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import shutil
import subprocess
import tempfile
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, Literal

import torch
from gaitforge.learner.checkpoint_meta import (
    META_FILE,
    CheckpointError,
    CheckpointMeta,
    parse_meta,
    read_meta,
)
from gaitforge.learner.policy import ActorCritic, build_policy
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

logger = logging.getLogger(__name__)

PREFIX = "ckpt-"
NORM_PREFIX = "norm."
FILES = ("policy.safetensors", "normalizer.safetensors", META_FILE)
OPTIMIZER_FILE = "optimizer.safetensors"
PACKAGES = ("gaitforge", "torch", "mujoco", "opensim", "ray", "gymnasium")

__all__ = [
    "CheckpointError",
    "CheckpointMeta",
    "checkpoints",
    "latest_checkpoint",
    "load_checkpoint",
    "load_optimizer_state",
    "load_policy",
    "read_meta",
    "restore_optimizer",
    "save_checkpoint",
    "select_checkpoint",
]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@functools.cache
def source_commit() -> str:
    """The git commit of the gaitforge source tree running now ("unknown" outside a git
    checkout), with ``-dirty`` if it has uncommitted changes."""
    here = Path(__file__).resolve().parent
    try:
        found = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--abbrev=40"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return found.stdout.strip() or "unknown"


def _versions() -> dict[str, str]:
    out = {}
    for package in PACKAGES:
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "not installed"
    out["gaitforge_commit"] = source_commit()
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
    meta: CheckpointMeta | Mapping[str, Any],
    keep_last: int = 3,
    best_metric: str | None = None,
    optimizer_state: dict | None = None,
) -> Path:
    """Write ``state`` (a policy ``state_dict``), ``meta`` and, if given, an optimizer's
    ``state_dict`` as a checkpoint under ``root``; keep the last ``keep_last`` and the best by
    ``best_metric``. ``meta``'s ``env_steps``, ``versions`` and ``optimizer_param_groups`` are
    set here; a mapping is validated as :class:`CheckpointMeta` first.

    Raises:
        CheckpointError: ``meta`` does not validate.
    """
    if not isinstance(meta, CheckpointMeta):
        meta = parse_meta(dict(meta), "meta")
    root.mkdir(parents=True, exist_ok=True)
    target = root / f"{PREFIX}{env_steps:012d}"
    tmp = Path(tempfile.mkdtemp(prefix=".tmp-", dir=root))
    try:
        tensors = {k: v.detach().contiguous().cpu() for k, v in state.items()}
        save_file(
            {k: v for k, v in tensors.items() if not k.startswith(NORM_PREFIX)}, tmp / FILES[0]
        )
        save_file({k: v for k, v in tensors.items() if k.startswith(NORM_PREFIX)}, tmp / FILES[1])
        update: dict[str, Any] = {"env_steps": env_steps, "versions": _versions()}
        files = list(FILES)
        if optimizer_state is not None:
            save_file(_flatten_optimizer(optimizer_state), tmp / OPTIMIZER_FILE)
            update["optimizer_param_groups"] = optimizer_state["param_groups"]
            files.append(OPTIMIZER_FILE)
        full_meta = meta.model_copy(update=update)
        (tmp / FILES[2]).write_text(full_meta.to_json())
        manifest = {name: _sha256(tmp / name) for name in files}
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2))
        for name in (*files, "manifest.json"):
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


def load_checkpoint(path: Path) -> tuple[dict[str, torch.Tensor], CheckpointMeta]:
    """The ``state_dict`` and metadata (any schema version, migrated) of the checkpoint
    directory ``path``.

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
    for name in FILES + ((OPTIMIZER_FILE,) if OPTIMIZER_FILE in manifest else ()):
        file = path / name
        if not file.exists():
            raise CheckpointError(f"{file}: missing")
        if _sha256(file) != manifest.get(name):
            raise CheckpointError(f"{file}: sha256 does not match the manifest (damaged)")
    try:
        state = {**load_file(path / FILES[0]), **load_file(path / FILES[1])}
    except SafetensorError as exc:
        raise CheckpointError(f"{path}: unreadable safetensors ({exc})") from None
    return state, read_meta(path)


def load_optimizer_state(path: Path) -> dict | None:
    """The optimizer ``state_dict`` saved in checkpoint ``path`` (already verified by
    :func:`load_checkpoint`), or None if it holds none."""
    file = path / OPTIMIZER_FILE
    if not file.exists():
        return None
    groups = read_meta(path).optimizer_param_groups
    if groups is None:
        raise CheckpointError(f"{path / META_FILE}: no 'optimizer_param_groups' for {file}")
    state: dict[int, dict[str, torch.Tensor]] = {}
    try:
        flat = load_file(file)
    except SafetensorError as exc:
        raise CheckpointError(f"{file}: unreadable safetensors ({exc})") from None
    for key, tensor in flat.items():
        index, name = key.split(".", 1)
        state.setdefault(int(index), {})[name] = tensor
    return {"state": state, "param_groups": groups}


def restore_optimizer(optimizer: torch.optim.Optimizer, path: Path) -> None:
    """Load checkpoint ``path``'s optimizer state into ``optimizer`` where it holds one and
    it fits; where its parameter groups changed (a ``critic_lr`` added to the job) Adam
    starts afresh, with a warning."""
    state = load_optimizer_state(path)
    if state is None:
        return
    try:
        optimizer.load_state_dict(state)
    except ValueError as exc:
        logger.warning("%s: Adam's state does not fit (%s); it starts afresh", path, exc)


def _flatten_optimizer(optimizer_state: dict) -> dict[str, torch.Tensor]:
    """``{"<param index>.<name>": tensor}``; scalars (Adam's ``step``) as 0-d tensors."""
    flat = {}
    for index, entries in optimizer_state["state"].items():
        for name, value in entries.items():
            tensor = value if isinstance(value, torch.Tensor) else torch.tensor(value)
            flat[f"{index}.{name}"] = tensor.detach().contiguous().cpu()
    return flat


def load_policy(path: Path) -> tuple[ActorCritic, CheckpointMeta]:
    """The policy of checkpoint ``path``, rebuilt from ``meta.network`` and loaded (eval
    mode), and the checkpoint's metadata."""
    state, meta = load_checkpoint(path)
    if meta.network is None:
        raise CheckpointError(f"{path / FILES[2]}: no 'network' description to rebuild from")
    try:
        policy = build_policy(meta.network)
        policy.load_state_dict(state)
    except (KeyError, ValueError, RuntimeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit meta.json's network ({exc})") from None
    policy.eval()
    return policy, meta


def checkpoints(root: Path) -> list[Path]:
    """Complete checkpoints under ``root``, oldest first."""
    return sorted(p for p in root.glob(f"{PREFIX}*") if (p / "manifest.json").exists())


def select_checkpoint(
    root: Path, pick: Literal["latest", "best"] = "latest", metric: str = "return"
) -> Path | None:
    """The checkpoint under ``root`` (a checkpoints directory) to use: the newest
    (``"latest"``), or the one with the highest finite ``metrics[metric]`` (``"best"``; a
    tie goes to the newest; checkpoints whose metadata does not read are skipped). None if
    there is none to choose."""
    found = checkpoints(root)
    if pick == "latest":
        return found[-1] if found else None
    scored = []
    for path in found:
        try:
            value = read_meta(path).metric(metric)
        except CheckpointError as exc:
            logger.debug("%s: skipped choosing the best (%s)", path, exc)
            continue
        if value is not None:
            scored.append((value, path.name, path))
    return max(scored)[2] if scored else None


def latest_checkpoint(root: Path) -> Path | None:
    """The newest checkpoint under ``root`` (``select_checkpoint(root, "latest")``)."""
    return select_checkpoint(root, "latest")


def _prune(root: Path, keep_last: int, best_metric: str | None) -> None:
    found = checkpoints(root)
    keep = set(found[-keep_last:])
    if best_metric is not None and (best := select_checkpoint(root, "best", best_metric)):
        keep.add(best)
    for path in found:
        if path not in keep:
            shutil.rmtree(path)
