"""Shipping a policy: a checkpoint copied without its optimizer or its run's episode history,
with a provenance, that evaluates and starts a job like any checkpoint."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import torch
from gaitforge.learner.checkpoint import load_checkpoint, load_policy
from gaitforge.learner.trainer import Trainer

from tests.learner.test_init_from import _job, _trained


def test_a_shipped_policy_keeps_the_weights_and_names_its_origin(tmp_path: Path) -> None:
    source = _trained(tmp_path)
    report = tmp_path / "eval.json"
    report.write_text(
        json.dumps(
            {
                "results": {
                    "deterministic": {
                        "scene": "elbow-reach",
                        "backend": "mujoco",
                        "fall_rate": {"value": 0.0, "n": 10},
                        "mean_speed_m_s": {"mean": 0.0, "n": 10},
                    }
                }
            }
        )
    )
    dest = tmp_path / "policies" / "elbow-reach"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "gaitforge.service.cli",
            "ship",
            str(source),
            str(dest),
            "--command",
            "gaitforge train elbow.yaml",
            "--evaluation",
            str(report),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert not (dest / "optimizer.safetensors").exists()
    umask = os.umask(0)
    os.umask(umask)
    assert dest.stat().st_mode & 0o777 == 0o777 & ~umask
    assert {p.stat().st_mode & 0o777 for p in dest.iterdir()} == {0o666 & ~umask}
    _, meta = load_checkpoint(dest)
    provenance = meta.provenance or {}
    assert provenance["command"] == "gaitforge train elbow.yaml" and provenance["seed"] == 0
    assert provenance["commit"] and provenance["copied_from"] == str(source)
    assert provenance["evaluation"]["fall_rate"] == 0.0
    assert meta.curriculum is not None and meta.curriculum.episodes == []
    assert load_checkpoint(source)[1].curriculum.episodes  # the run had some
    shipped, _ = load_policy(dest)
    original, _ = load_policy(source)
    obs = torch.randn(16, original.obs_dim)
    # exactly: the same weights through the same network in this process
    assert torch.equal(shipped.mean_action(obs), original.mean_action(obs))
    trainer = Trainer(_job(dest), tmp_path / "from-shipped", tensorboard=False)
    assert trainer.lineage[0]["source"] == str(dest)


def test_shipping_a_non_checkpoint_fails_with_one_line(tmp_path: Path) -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "gaitforge.service.cli",
            "ship",
            str(tmp_path),
            str(tmp_path / "x"),
            "--command",
            "c",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2 and "manifest.json: missing" in done.stderr
    assert not (tmp_path / "x").exists()
