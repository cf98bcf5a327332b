"""Evaluation on the real MuJoCo simulator: metrics consistent with the body's motion, falls
counted, seeded runs repeat exactly, the sweep lowers the target speed, the CLI's errors."""

from __future__ import annotations

import json
import logging
import math
import shutil
import statistics
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from gaitforge.learner.checkpoint import CheckpointError, load_policy, save_checkpoint
from gaitforge.learner.evaluation.evaluate import (
    EvaluationError,
    evaluate_checkpoint,
    evaluate_episode,
    evaluate_policy,
    make_runner,
    resolve_checkpoint,
    speed_sweep,
    with_target_speed,
)
from gaitforge.learner.evaluation.stats import Rate, Stat
from gaitforge.learner.policy import BlendedPolicy, GaussianPolicy
from gaitforge.service.cli import app
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.episode import EpisodeSummary, Observer
from gaitforge.workers.scenes import Scene, load_scene, scene_fields
from typer.testing import CliRunner

from tests.workers.test_obstacle_touch import obstacle_scene

runner = CliRunner()
WALK_OBS, WALK_ACT = 61, 18


def short_scene(tmp_path: Path, name: str = "walk-2d", episode_s: float = 1.5) -> Path:
    """A catalogue scene with a shorter episode, as a YAML file under ``tmp_path``."""
    data = scene_fields(name)
    data["episode_s"] = episode_s
    path = tmp_path / f"{name}-short.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def relaxed_policy(obs_dim: int = WALK_OBS, act_dim: int = WALK_ACT) -> GaussianPolicy:
    """Mean excitation sigmoid(-30) ~ 1e-13: every muscle relaxed."""
    policy = GaussianPolicy(obs_dim, act_dim, hidden=(16,))
    with torch.no_grad():
        last = policy.actor[-1]
        last.weight.zero_()
        last.bias.fill_(-30.0)
    return policy.eval()


def save(root: Path, policy: GaussianPolicy, scene: Scene, env_steps: int = 0, **metrics) -> Path:
    meta = {
        "network": policy.describe(),
        "scene": scene.model_dump(mode="json"),
        "config": {"backend": "mujoco"},
        "metrics": metrics,
    }
    return save_checkpoint(root, env_steps, policy.state_dict(), meta, keep_last=5)


@pytest.fixture(scope="module")
def walk(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Scene]:
    """A run directory with one checkpoint of a randomly initialised walk-2d policy."""
    tmp = tmp_path_factory.mktemp("walk")
    scene = load_scene(short_scene(tmp))
    torch.manual_seed(0)
    save(tmp / "run" / "checkpoints", GaussianPolicy(WALK_OBS, WALK_ACT, hidden=(16,)), scene)
    return tmp / "run", scene


class PelvisTrace(Observer):
    """Observer: the pelvis forward position (m) at reset and after every step."""

    def __init__(self) -> None:
        self.forward: list[float] = []
        self.ended: list[EpisodeSummary | None] = []

    def _log(self, env: MuscleEnv) -> None:
        self.forward.append(float(env.sim.state().pelvis_pos[env.sim.forward_axis]))

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict) -> None:
        self._log(env)

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self._log(env)

    def on_end(self, summary: EpisodeSummary | None) -> None:
        self.ended.append(summary)


def test_relaxed_muscles_fall_and_the_metrics_agree_with_the_motion(tmp_path: Path) -> None:
    scene = load_scene(short_scene(tmp_path, episode_s=4.0))
    policy = relaxed_policy()
    trace = PelvisTrace()
    with make_runner(policy, scene, "mujoco") as runner:
        episode = evaluate_episode(runner, policy, seed=3, observers=[trace])
    assert len(trace.ended) == 1 and trace.ended[0] is not None
    assert trace.ended[0].steps == episode.steps and trace.ended[0].fell
    # with every muscle relaxed the legs fold: a fall within a couple of seconds
    assert episode.fell and not episode.truncated and episode.health == "ok"
    assert 0.1 < episode.time_s < 2.5
    assert episode.steps == len(trace.forward) - 1
    assert episode.time_s == pytest.approx(episode.steps / scene.control_hz)
    assert episode.distance_m == pytest.approx(trace.forward[-1] - trace.forward[0], abs=1e-12)
    assert episode.mean_speed_m_s == pytest.approx(episode.distance_m / episode.time_s)
    assert episode.effort == pytest.approx(0.0, abs=1e-12)
    assert episode.return_ == pytest.approx(sum(episode.reward_terms.values()))

    result = evaluate_policy(policy, scene, episodes=3, seed=10)
    assert result.fall_rate.value == 1.0 and result.fall_rate.count == 3
    assert 0.0 <= result.fall_rate.low <= result.fall_rate.high <= 1.0
    assert result.health == {"ok": 3} and result.failure_rate.value == 0.0
    assert result.survival_rate.count == 0
    assert [e.seed for e in result.episodes] == [10, 11, 12]


def test_a_reach_task_never_falls_and_effort_is_the_mean_squared_excitation(
    tmp_path: Path,
) -> None:
    scene = load_scene("elbow-reach")
    policy = relaxed_policy(15, 6)
    with torch.no_grad():
        policy.actor[-1].bias.fill_(0.0)  # every excitation 0.5
    result = evaluate_policy(policy, scene, episodes=2)
    assert result.fall_rate.value == 0.0
    for e in result.episodes:
        assert e.truncated and e.steps == scene.steps_per_episode
        assert e.distance_m == 0.0
        assert e.effort == pytest.approx(0.25)
        assert e.effort_sum == pytest.approx(0.25 * 6 * e.steps)


def test_seeded_runs_repeat_exactly_in_both_modes(walk: tuple[Path, Scene]) -> None:
    run, _ = walk
    first = evaluate_checkpoint(run, episodes=2, modes=("deterministic", "stochastic"))
    again = evaluate_checkpoint(run, episodes=2, modes=("deterministic", "stochastic"))
    assert first.to_dict() == again.to_dict()  # exactly: both in this process, same machine
    det, sto = first.results["deterministic"], first.results["stochastic"]
    assert det.episodes[0].return_ != sto.episodes[0].return_
    assert det.effort.mean < sto.effort.mean  # noise adds excitation^2 on average
    assert first.scene == "walk-2d" and first.backend == "mujoco" and first.env_steps == 0


def test_the_sweep_lowers_the_target_speed_as_asked(walk: tuple[Path, Scene]) -> None:
    run, scene = walk
    report = evaluate_checkpoint(run, episodes=2, sweep=[0.0, 0.15, 0.3])
    targets = [p.target_speed_m_s for p in report.sweep]
    assert targets == pytest.approx([1.25, 1.25 * 0.85, 1.25 * 0.7])
    assert [p.result.target_speed_m_s for p in report.sweep] == pytest.approx(targets)
    for p in report.sweep:
        assert 0.0 <= p.result.fall_rate.value <= 1.0
    # reduction 0 is the scene itself, same seeds: the same episodes
    assert report.sweep[0].result.episodes == report.results["deterministic"].episodes
    # the policy is told the lower target: it is in the observation
    env = MuscleEnv(with_target_speed(scene, targets[2]))
    obs, _ = env.reset(seed=0)
    assert obs[env.obs_names.index("target_speed")] == pytest.approx(1.25 * 0.7)

    with pytest.raises(EvaluationError, match="no target speed"):
        speed_sweep(relaxed_policy(15, 6), load_scene("elbow-reach"))
    with pytest.raises(EvaluationError, match=r"\[0, 1\)"):
        evaluate_checkpoint(run, episodes=1, sweep=[0.1, 1.5])


def test_json_is_complete(walk: tuple[Path, Scene], tmp_path: Path) -> None:
    run, _ = walk
    out = tmp_path / "eval.json"
    result = runner.invoke(
        app,
        [
            "evaluate",
            str(run),
            "--episodes",
            "2",
            "--mode",
            "both",
            "--sweep",
            "--sweep-percent",
            "0,20",
            "--per-episode",
            "--json-out",
            str(out),
        ],
        env={"COLUMNS": "200"},
    )
    assert result.exit_code == 0, result.output
    assert "Speed against safety" in result.output and "fall rate" in result.output
    assert "Episodes (stochastic)" in result.output
    data = json.loads(out.read_text())
    assert set(data["results"]) == {"deterministic", "stochastic"}
    det = data["results"]["deterministic"]
    assert len(det["episodes"]) == 2 and set(det["fall_rate"]) >= {"value", "low", "high"}
    assert det["return"]["mean"] == pytest.approx(
        sum(e["return"] for e in det["episodes"]) / 2, rel=1e-9
    )
    assert [p["target_speed_m_s"] for p in data["sweep"]] == pytest.approx([1.25, 1.0])


def test_another_scene_must_have_the_policy_sizes(walk: tuple[Path, Scene]) -> None:
    run, _ = walk
    with pytest.raises(EvaluationError) as caught:
        evaluate_checkpoint(run, scene="elbow-reach", episodes=1)
    message = str(caught.value)
    assert "15" in message and "6" in message and "61" in message and "18" in message
    report = evaluate_checkpoint(run, scene="run-2d", episodes=1)  # same body, faster target
    assert report.scene == "run-2d"
    assert (
        report.results["deterministic"].target_speed_m_s == load_scene("run-2d").task.target_speed
    )


def test_a_scene_that_observes_more_gets_zero_weights_for_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The shipped runner on the obstacles before it learned them: the 3 obstacle inputs are
    added with zero weights (its actions are those it takes without them)."""
    runner = Path(__file__).parents[2] / "examples" / "policies" / "run-2d"
    with caplog.at_level(logging.WARNING, logger="gaitforge.learner.evaluation.evaluate"):
        report = evaluate_checkpoint(runner, scene="obstacles-2d+clock", episodes=1)
    assert report.scene == "obstacles-2d+clock"
    assert "obstacle_dx" in caplog.text and "zero weights" in caplog.text
    assert report.results["deterministic"].episodes[0].steps > 25  # it got going


def test_a_run_directory_gives_its_latest_or_best(tmp_path: Path) -> None:
    scene = load_scene("elbow-reach")
    root = tmp_path / "checkpoints"
    policy = relaxed_policy(15, 6)
    first = save(root, policy, scene, 100, **{"return": 5.0})
    last = save(root, policy, scene, 200, **{"return": 1.0})
    assert resolve_checkpoint(tmp_path) == last
    assert resolve_checkpoint(root) == last
    assert resolve_checkpoint(tmp_path, "best") == first
    assert resolve_checkpoint(first) == first
    (tmp_path / "empty").mkdir()
    with pytest.raises(EvaluationError, match="no checkpoint"):
        resolve_checkpoint(tmp_path / "empty")
    with pytest.raises(EvaluationError, match="no such file"):
        resolve_checkpoint(tmp_path / "missing")


def test_statistics() -> None:
    # Student's t (two-sided 95 %): the printed tables' quantiles, to their 3 decimals
    for values, t975 in (
        ([1.0, 2.0, 3.0], 4.303),
        ([1.0, 2.0], 12.706),
        ([0.0] * 40 + [1.0], 2.021),
    ):
        s = Stat.of(values)
        half = t975 * statistics.stdev(values) / math.sqrt(len(values))
        assert s.mean == statistics.fmean(values)
        assert s.high - s.mean == pytest.approx(half, rel=2e-4)
        assert s.mean - s.low == pytest.approx(half, rel=2e-4)
    assert Stat.of([4.0]) == Stat(4.0, 4.0, 4.0, 0.0, 1)
    assert Stat.of([2.0, 2.0, 2.0]) == Stat(2.0, 2.0, 2.0, 0.0, 3)
    # Wilson's score interval, against its closed form
    r = Rate.of(0, 10)
    assert r.value == 0.0 and r.low == 0.0 and r.high == pytest.approx(0.2775, abs=1e-4)
    z, p, n = 1.959964, 0.3, 10
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / (1 + z**2 / n)
    r = Rate.of(3, 10)
    assert (r.low, r.high) == pytest.approx((centre - half, centre + half), abs=1e-6)
    assert Rate.of(10, 10).high == 1.0 and math.isnan(Rate.of(0, 0).value)


def one_line_error(args: list[str]) -> str:
    result = runner.invoke(app, ["evaluate", *args], env={"COLUMNS": "80"})
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_cli_errors_are_one_line(walk: tuple[Path, Scene], tmp_path: Path) -> None:
    run, _ = walk
    assert "no such file" in one_line_error([str(tmp_path / "missing")])
    assert "episodes must be > 0" in one_line_error([str(run), "--episodes", "0"])
    line = one_line_error([str(run), "--scene", "walk-9d"])
    assert "walk-9d" in line and "unknown" in line
    assert "observation size" in one_line_error([str(run), "--scene", "elbow-reach"])
    assert "no checkpoint" in one_line_error([str(tmp_path)])
    assert "in [0, 100)" in one_line_error([str(run), "--sweep", "--sweep-percent", "0,150"])
    damaged = tmp_path / "damaged"
    shutil.copytree(run, damaged)
    ckpt = resolve_checkpoint(damaged)
    with (ckpt / "policy.safetensors").open("ab") as f:
        f.write(b"x")
    line = one_line_error([str(damaged)])
    assert "policy.safetensors" in line and "damaged" in line
    with pytest.raises(CheckpointError):
        evaluate_checkpoint(damaged, episodes=1)


def test_the_first_episode_is_recorded(walk: tuple[Path, Scene], tmp_path: Path) -> None:
    from gaitforge.learner.evaluation.recording import TOPICS
    from mcap.reader import make_reader

    run, _ = walk
    out = tmp_path / "first.mcap"
    report = evaluate_checkpoint(run, episodes=2, record=out)
    assert report.recording == str(out)
    first = report.results["deterministic"].episodes[0]
    with out.open("rb") as f:
        reader = make_reader(f)
        counts: dict[str, int] = {}
        for _, channel, _ in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts == dict.fromkeys(TOPICS, first.steps)
    with out.open("rb") as f:
        (meta,) = [m.metadata for m in make_reader(f).iter_metadata()]
    assert meta["mode"] == "deterministic" and meta["seed"] == "0"
    assert len(meta["checkpoint_sha256"]) == 64 and meta["scene"] == "walk-2d"


def test_the_first_episode_as_a_video(walk: tuple[Path, Scene], tmp_path: Path) -> None:
    video = pytest.importorskip("gaitforge.learner.evaluation.video")
    if (why := video.osmesa_available()) is not None:
        pytest.skip(f"no offscreen rendering here: {why}")
    run, _ = walk
    out = tmp_path / "first.mp4"
    report = evaluate_checkpoint(run, episodes=1, video=out)
    assert report.video == str(out)
    assert out.stat().st_size > 1000
    assert out.read_bytes()[4:8] == b"ftyp"  # an MP4 container


def test_a_checkpoint_the_trainer_wrote_mid_blend(tmp_path: Path) -> None:
    from gaitforge.learner.job import Job
    from gaitforge.learner.trainer import Trainer

    job = Job.model_validate(
        {
            "name": "walk-blend",
            "network": {"hidden": [8]},
            "checkpoint": {"every_iters": 1},
            "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 16},
            "ppo": {"batch_env_steps": 32, "minibatch_size": 32, "epochs": 1},
            "stages": [
                {"scene": "walk-2d", "env_steps": 32},
                {
                    "scene": "walk-2d",
                    "env_steps": 32,
                    "transition": "blend",
                    "network": {"hidden": [16]},
                    "blend": {
                        "ramp_env_steps": 1024,
                        "critic_warmup_env_steps": 32,
                        "fit_epochs": 1,
                    },
                },
            ],
        }
    )
    Trainer(job, tmp_path, tensorboard=False).run()
    policy, _ = load_policy(resolve_checkpoint(tmp_path))
    assert isinstance(policy, BlendedPolicy)  # alpha still ramping: pi_old and pi_new both act
    report = evaluate_checkpoint(tmp_path, episodes=1, modes=("deterministic", "stochastic"))
    assert report.scene == "walk-2d" and report.stage is not None and report.stage["index"] == 1
    assert report.env_steps is not None and report.env_steps >= 64
    for result in report.results.values():
        assert result.episodes[0].steps > 0 and 0.0 <= result.fall_rate.value <= 1.0


class PoseErrors(Observer):
    """Observer: every step's ``info["imitation"]``."""

    def __init__(self) -> None:
        self.steps: list[dict] = []

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.steps.append(dict(info["imitation"]))


def evaluate_run_dir(run: Path, out: Path, episodes: int) -> tuple[str, dict]:
    """``gaitforge evaluate RUN --per-episode`` on a wide terminal: its printed output and the
    deterministic results of the JSON it wrote to ``out``."""
    args = ["evaluate", str(run), "--episodes", str(episodes), "--per-episode"]
    printed = runner.invoke(app, [*args, "--json-out", str(out)], env={"COLUMNS": "200"})
    assert printed.exit_code == 0, printed.output
    return printed.output, json.loads(out.read_text())["results"]["deterministic"]


def test_imitation_scenes_report_tracking_error_and_kept_gait(tmp_path: Path) -> None:
    scene = load_scene(short_scene(tmp_path, "imitate-walk-2d", episode_s=0.4))  # 10 steps
    n_obs = len(MuscleEnv(scene).obs_names)
    policy = relaxed_policy(n_obs, WALK_ACT)
    with torch.no_grad():
        policy.actor[-1].bias.fill_(-1.5)  # excitation ~0.18
    trace = PoseErrors()
    result = evaluate_policy(policy, scene, episodes=4, seed=0, observers=[trace])
    first = result.episodes[0]
    errors = [s["pose_error_rad"] for s in trace.steps]
    assert len(errors) == first.steps
    assert first.tracking_error_rad == pytest.approx(math.sqrt(np.mean(np.square(errors))))
    kept = all(s["kept"] for s in trace.steps) and first.truncated
    assert first.kept_gait == kept
    for e in result.episodes:
        assert e.kept_gait == (e.truncated and not e.fell and e.health == "ok")  # bound held
    assert result.tracking_error_rad is not None and result.kept_gait_rate is not None
    assert result.tracking_error_rad.n == 4 and result.kept_gait_rate.n == 4
    assert result.tracking_error_rad.mean == pytest.approx(
        np.mean([e.tracking_error_rad for e in result.episodes])
    )
    assert result.kept_gait_rate.count == sum(bool(e.kept_gait) for e in result.episodes)
    # weak constant excitations: some episodes drift past the bound early, some do not
    assert 0 < result.kept_gait_rate.count < 4
    assert result.kept_gait_rate.low <= result.kept_gait_rate.value <= result.kept_gait_rate.high

    # the printed tables and the JSON carry them; a non-imitation scene's do not
    run = tmp_path / "run"
    save(run / "checkpoints", policy, scene)
    printed, det = evaluate_run_dir(run, tmp_path / "eval.json", episodes=2)
    assert "tracking rad" in printed and "kept gait" in printed
    assert det["tracking_error_rad"]["n"] == 2 and det["kept_gait_rate"]["n"] == 2
    assert all(isinstance(e["kept_gait"], bool) for e in det["episodes"])


def test_other_scenes_have_no_tracking_columns(walk: tuple[Path, Scene], tmp_path: Path) -> None:
    run, _ = walk
    printed, det = evaluate_run_dir(run, tmp_path / "eval.json", episodes=1)
    assert "tracking" not in printed and "kept" not in printed
    assert det["tracking_error_rad"] is None and det["kept_gait_rate"] is None
    assert det["episodes"][0]["tracking_error_rad"] is None
    assert "touched" not in printed and det["touched_rate"] is None
    assert det["episodes"][0]["obstacle_contact_steps"] is None
    assert "turned" not in printed and det["episodes"][0]["turned_deg"] == 0.0  # planar


def test_a_3d_body_reports_how_far_its_pelvis_turned(tmp_path: Path) -> None:
    scene = load_scene(short_scene(tmp_path, "walk-3d", episode_s=0.6))
    env = MuscleEnv(scene)
    policy = relaxed_policy(len(env.obs_names), len(env.act_names))
    env.close()
    run = tmp_path / "run"
    save(run / "checkpoints", policy, scene)
    printed, det = evaluate_run_dir(run, tmp_path / "eval.json", episodes=2)
    turns = [e["turned_deg"] for e in det["episodes"]]
    assert any(t != 0.0 for t in turns)
    assert det["turned_deg"]["mean"] == pytest.approx(np.mean(np.abs(turns)))
    assert "turned deg" in printed and f"{turns[0]:+.0f}" in printed


def test_obstacle_scenes_tell_the_falls_after_a_touch_from_the_others(tmp_path: Path) -> None:
    """Spheres under the standing feet are touched from the first step; spheres 20 m ahead
    never; the evaluation splits the falls by it, and a scene without obstacles has none of
    it."""
    under = obstacle_scene(tmp_path, [0.0, 0.0], "spheres-under-the-feet")
    ahead = obstacle_scene(tmp_path, [20.0, 30.0], "spheres-far-ahead")
    for scene, touching in ((under, True), (ahead, False), (load_scene("walk-2d"), None)):
        env = MuscleEnv(scene)
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape))
        assert env.touching_obstacle() is touching, scene.name

    policy = relaxed_policy(len(MuscleEnv(under).obs_names), WALK_ACT)
    touched = evaluate_policy(policy, under, episodes=2, seed=0)
    assert all(e.first_obstacle_touch_s == pytest.approx(0.01) for e in touched.episodes)
    assert all(e.obstacle_contact_steps >= 1 for e in touched.episodes)
    assert touched.touched_rate.count == 2 and touched.fall_rate_untouched.n == 0
    assert touched.fall_rate_touched.count == sum(e.fell for e in touched.episodes)
    clear = evaluate_policy(policy, ahead, episodes=2, seed=0)
    assert [e.obstacle_contact_steps for e in clear.episodes] == [0, 0]
    assert all(e.first_obstacle_touch_s is None for e in clear.episodes)
    assert clear.touched_rate.count == 0 and clear.fall_rate_touched.n == 0
    assert clear.fall_rate_untouched.n == 2

    run = tmp_path / "run"
    save(run / "checkpoints", policy, under)
    printed, det = evaluate_run_dir(run, tmp_path / "eval.json", episodes=1)
    assert "touched an obstacle" in printed and "falls if not" in printed
    assert det["touched_rate"]["count"] == 1 and det["episodes"][0]["obstacle_contact_steps"] >= 1
