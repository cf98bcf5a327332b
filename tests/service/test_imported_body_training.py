"""A short training run on an imported OpenSim body: ``examples/stand-3d.yaml`` (gait2354,
imported by ``gaitforge bodies import``) trains on MuJoCo, and the policy it makes runs on
both MuJoCo and OpenSim (real simulators, in-process rollouts)."""

from __future__ import annotations

from pathlib import Path

import gaitforge

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_the_stand_recipe_trains_on_an_imported_body_and_runs_on_both_simulators(
    tmp_path: Path,
) -> None:
    result = gaitforge.train(
        EXAMPLES / "stand-3d.yaml",
        tmp_path / "run",
        overrides={
            "workers.num_workers": 0,
            "workers.envs_per_worker": 2,
            "workers.fragment_length": 64,
            "ppo.batch_env_steps": 256,
            "ppo.minibatch_size": 64,
            "ppo.epochs": 1,
            "stages.0.env_steps": 512,
            "stages.0.evaluate.episodes": 1,
        },
        tensorboard=False,
    )
    assert result.finished and result.env_steps == 512 and result.checkpoint is not None
    for backend in ("mujoco", "opensim"):
        report = gaitforge.evaluate(
            result.checkpoint,
            scene="stand-3d",  # the catalogue scene runs on both; the job set its control
            backend=backend,
            overrides={"control_hz": 25, "action.kind": "joint_targets", "episode_s": 0.3},
            episodes=1,
        )
        (episode,) = report.results["deterministic"].episodes
        assert episode.steps > 0, backend
