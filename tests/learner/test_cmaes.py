"""CMA-ES on the reflex gait controller (``learner.cmaes``): generations in-process, the
state saved after each, and a resumed run goes on as one that never stopped."""

from __future__ import annotations

import csv
import functools
from pathlib import Path

import pytest
from gaitforge.learner.cmaes import CmaesTuning
from gaitforge.learner.stage_spec import StageOptimize
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene

SCENE = load_scene("reflex-walk-3d", {"episode_s": 0.3}).resolved()
SETTINGS = StageOptimize(population=4, generations=3, episodes=1, sigma=0.2)
WORKER = RolloutWorker(SCENE, functools.partial(UniformExcitationPolicy, 22), num_envs=1)


def _rows(run_dir: Path) -> list[dict[str, str]]:
    with (run_dir / "progress.csv").open() as f:
        return list(csv.DictReader(f))


def test_a_resumed_search_goes_on_as_one_that_never_stopped(tmp_path: Path) -> None:
    straight = CmaesTuning(SCENE, SETTINGS, tmp_path / "straight", WORKER, False, seed=5)
    straight.run()
    first = CmaesTuning(
        SCENE, SETTINGS.model_copy(update={"generations": 2}), tmp_path / "resumed", WORKER, seed=5
    )
    first.run()
    resumed = CmaesTuning(SCENE, SETTINGS, tmp_path / "resumed", WORKER, False, seed=5)
    assert resumed.saved.generation == 2
    resumed.run()
    a, b = _rows(tmp_path / "straight"), _rows(tmp_path / "resumed")
    assert [r["generation"] for r in b] == ["1", "2", "3"]
    for row_a, row_b in zip(a, b, strict=True):
        for key in ("best", "mean", "sigma", "env_steps"):
            assert float(row_b[key]) == pytest.approx(float(row_a[key]), rel=1e-9), key
    tuned = load_scene(str(tmp_path / "resumed" / "tuned.yaml"))
    assert tuned.action.parameters == pytest.approx(resumed.tuned_parameters(), rel=1e-12)
    assert (tmp_path / "resumed" / "tb").is_dir()  # the first part wrote TensorBoard


def test_a_scene_without_the_controller_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="not reflex_gait"):
        CmaesTuning(load_scene("walk-2d").resolved(), SETTINGS, tmp_path, WORKER)
