"""The one episode loop on the real MuJoCo simulator: observers see reset, every step and the
end once (also when the episode fails), the summary agrees with what the env returned."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.episode import EpisodeRunner, EpisodeSummary, Observer, run_episode


class Log(Observer):
    """Every call, in order, with what the loop passed."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.rewards: list[float] = []
        self.actions: list[np.ndarray] = []
        self.last_info: dict[str, Any] = {}
        self.summary: EpisodeSummary | None = None

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        assert obs.shape == env.observation_space.shape and info["health"] == "ok"
        self.calls.append("reset")

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.calls.append("step")
        self.rewards.append(reward)
        self.actions.append(action)
        self.last_info = info

    def on_end(self, summary: EpisodeSummary | None) -> None:
        self.calls.append("end")
        self.summary = summary


def test_a_whole_episode_is_seen_once_and_summed() -> None:
    log = Log()
    with EpisodeRunner("elbow-reach") as runner:
        assert runner.obs_names == runner.env.obs_names
        assert runner.act_names == runner.env.sim.muscle_names and len(runner.act_names) == 6
        summary = runner.run(lambda obs: np.full(6, 1.5), seed=2, observers=[log])
        steps = runner.scene.steps_per_episode
    assert log.calls == ["reset", *["step"] * steps, "end"]
    assert log.summary == summary
    assert summary.steps == steps and summary.truncated and not summary.terminated
    assert summary.return_ == pytest.approx(sum(log.rewards))
    assert summary.time_s == pytest.approx(steps / runner.scene.control_hz)
    assert summary.sim_time_s == pytest.approx(log.last_info["sim_time"])
    assert summary.health == "ok" and not summary.fell and summary.seed == 2
    assert all(np.array_equal(a, np.ones(6)) for a in log.actions)  # as applied: clipped


def test_max_steps_and_the_same_seed_repeat() -> None:
    env = MuscleEnv("walk-2d")
    first, again = Log(), Log()
    a = run_episode(env, lambda obs: np.full(18, 0.2), 5, [first], max_steps=7)
    b = run_episode(env, lambda obs: np.full(18, 0.2), 5, [again], max_steps=7)
    # exactly: the same seed twice in this process on this machine is the same episode
    assert a == b and a.steps == 7 and not (a.terminated or a.truncated)
    assert a.distance_m == first.last_info["distance"]


def test_a_failing_episode_still_ends_every_observer() -> None:
    env = MuscleEnv("elbow-reach")
    logs = [Log(), Log()]
    calls = 0

    def act(obs: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        if calls == 3:
            raise RuntimeError("policy broke")
        return np.zeros(6)

    with pytest.raises(RuntimeError, match="policy broke"):
        run_episode(env, act, 0, logs)
    for log in logs:
        assert log.calls == ["reset", "step", "step", "end"] and log.summary is None


def test_the_learner_builds_envs_only_through_the_runner() -> None:
    """Outside ``workers`` (the pool's actors), envs are built by :class:`EpisodeRunner`."""
    import ast
    from pathlib import Path

    import gaitforge.learner

    builders = {"MuscleEnv", "make_simulator", "make"}
    found = []
    for path in Path(gaitforge.learner.__path__[0]).glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                func = node.func
                name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
                if name in builders and not (name == "make" and "gym" not in ast.unparse(func)):
                    found.append(f"{path.name}:{node.lineno}: {ast.unparse(node)}")
    assert not found, found
