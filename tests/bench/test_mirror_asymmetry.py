"""bench/mirror_asymmetry.py: a policy against its own mirror image, on real MuJoCo episodes
of checkpoints written here (a symmetric and a one-sided policy)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pytest
import torch
from gaitforge.learner.checkpoint import save_checkpoint
from gaitforge.learner.policy import GaussianPolicy
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene

if TYPE_CHECKING:
    from conftest import RunBench

SCENE = "walk-2d+clock"


def _constant_policy(root: Path, one_sided: float) -> Path:
    """A checkpoint whose mean action ignores the observation: sigmoid(+one_sided) on the
    right side's actions, sigmoid(-one_sided) on the left's, noise 0.05."""
    scene = load_scene(SCENE).resolved()
    env = MuscleEnv(scene)
    names = env.act_names
    policy = GaussianPolicy(len(env.obs_names), len(names), hidden=(16,), init_std=0.05)
    env.close()
    with torch.no_grad():
        policy.actor[-1].weight.zero_()
        side = [one_sided if n.endswith("_r") else -one_sided for n in names]
        policy.actor[-1].bias.copy_(torch.tensor(side))
    meta = {
        "network": policy.describe(),
        "scene": scene.model_dump(mode="json"),
        "config": {"backend": "mujoco"},
        "metrics": {},
    }
    return save_checkpoint(root, 0, policy.state_dict(), meta)


def _cells(stdout: str, first: str) -> list[str]:
    """The cells of the table row whose first cell is ``first``."""
    rows = [[c.strip() for c in line.split("│")[1:-1]] for line in stdout.splitlines()]
    return next(cells for cells in rows if cells and cells[0] == first)


def test_a_symmetric_policy_has_no_gap_and_a_one_sided_one_puts_its_images_in_its_tail(
    tmp_path: Path, run_bench: RunBench
) -> None:
    symmetric = _constant_policy(tmp_path / "symmetric", 0.0)
    one_sided = _constant_policy(tmp_path / "one-sided", 2.0)
    result = run_bench(
        "mirror_asymmetry.py",
        str(symmetric),
        "--episodes",
        "1",
        "--update-to",
        str(symmetric),
    )
    assert result.returncode == 0, result.stderr
    _, _, _, noise, gap, sampled, images = _cells(result.stdout, symmetric.name)
    assert noise == "0.050" and gap == "0.000, 0.000"
    assert images == sampled  # the images are the samples' entries, swapped
    for actions in ("sampled", "images"):  # an update to the same network moves nothing
        assert _cells(result.stdout, actions)[1:] == ["0", "0"]
    result = run_bench("mirror_asymmetry.py", str(one_sided), "--episodes", "1")
    assert result.returncode == 0, result.stderr
    _, _, _, _, gap, sampled, images = _cells(result.stdout, one_sided.name)
    spread = 2 * torch.sigmoid(torch.tensor(2.0)).item() - 1  # sigmoid(2) - sigmoid(-2)
    # the network's float32 gap, printed to 0.001: within that of the closed form
    assert [float(g) for g in gap.split(", ")] == pytest.approx([spread, spread], abs=1e-3)
    assert float(sampled) < 4 < spread / 0.05 - 4 < float(images)


def test_a_missing_checkpoint_or_a_scene_of_other_inputs_is_one_line(
    tmp_path: Path, run_bench: RunBench
) -> None:
    missing = run_bench("mirror_asymmetry.py", str(tmp_path / "nothing"))
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    assert str(tmp_path / "nothing") in missing.stderr
    checkpoint = _constant_policy(tmp_path / "planar", 0.0)
    other = run_bench("mirror_asymmetry.py", str(checkpoint), "--scene", "walk-3d+clock")
    assert other.returncode == 2 and "Traceback" not in other.stderr
    assert "the policy expects observation size" in other.stderr
