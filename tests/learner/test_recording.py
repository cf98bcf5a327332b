"""Recordings: MCAP files read back with the ``mcap`` reader, MP4s decoded with ffmpeg.

Real simulators (walk-2d on MuJoCo and OpenSim) driven by uniform random excitations.
"""

from __future__ import annotations

import json
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
import torch
from gaitforge.learner.checkpoint import save_checkpoint
from gaitforge.learner.evaluation.recording import (
    METADATA_NAME,
    SCALAR_TOPICS,
    TOPICS,
    EpisodeRecorder,
    checkpoint_metadata,
    record_episode,
)
from gaitforge.learner.evaluation.video import MujocoReplay, osmesa_available, record_video
from gaitforge.workers.env import MuscleEnv
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader

SCHEMAS = {
    "/tf": "foxglove.FrameTransforms",
    "/scene": "foxglove.SceneUpdate",
    "/joints": "foxglove.JointStates",
    "/reward": "gaitforge.Reward",
    "/speed": "gaitforge.Speed",
    "/activations": "gaitforge.Activations",
    "/excitations": "gaitforge.Excitations",
    "/foot_forces": "gaitforge.FootForces",
    "/health": "gaitforge.Health",
}


def _decode(schema, data: bytes):
    """A protobuf message from an MCAP schema record (a FileDescriptorSet) and its bytes."""
    files = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
    pool = descriptor_pool.DescriptorPool()
    for proto in files.file:
        pool.Add(proto)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name)).FromString(data)


def _record_by_hand(env: MuscleEnv, path: Path, steps: int, seed: int) -> list[dict]:
    """Step ``env`` with random excitations, recording; returns per step the sim time and
    pelvis position and activations read from the simulator."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    truth = []
    meta = {"checkpoint": "sha256:feed", "stage": "test"}
    with EpisodeRecorder(path, env, meta) as recorder:
        for _ in range(steps):
            action = rng.uniform(0.0, 1.0, len(env.sim.muscle_names))
            _, _, terminated, truncated, info = env.step(action)
            recorder.log_step(env, action, info["reward_terms"], info)
            state = env.sim.state()
            truth.append(
                {
                    "time": state.time,
                    "pelvis": state.pelvis_pos.copy(),
                    "activations": state.activations.copy(),
                }
            )
            if terminated or truncated:
                break
    return truth


def _check_file(path: Path, truth: list[dict], backend: str) -> None:
    steps = len(truth)
    times = [round(t["time"] * 1e9) for t in truth]
    with path.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        channels = {c.topic: c for c in summary.channels.values()}
        assert set(channels) == set(TOPICS) == set(SCHEMAS)
        for topic, channel in channels.items():
            assert summary.schemas[channel.schema_id].name == SCHEMAS[topic], topic
            assert summary.statistics.channel_message_counts[channel.id] == steps, topic
        for topic in SCALAR_TOPICS:
            assert channels[topic].message_encoding == "json"
        (meta,) = [m for m in reader.iter_metadata() if m.name == METADATA_NAME]
        assert meta.metadata["scene"] == "walk-2d"
        assert meta.metadata["backend"] == backend
        assert meta.metadata["profile"] == "default"
        assert meta.metadata["checkpoint"] == "sha256:feed"
        log_times: dict[str, list[int]] = {topic: [] for topic in TOPICS}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            log_times[channel.topic].append(message.log_time)
            k = len(log_times[channel.topic]) - 1
            if channel.topic == "/tf" and k == steps - 1:
                tf = _decode(schema, message.data)
                pelvis = next(t for t in tf.transforms if t.child_frame_id == "pelvis")
                assert tf.transforms[0].parent_frame_id == "world"
                # Y-up body to Z-up Foxglove: forward stays x, up becomes z
                x, y, up = truth[k]["pelvis"]
                assert pelvis.translation.x == pytest.approx(x)
                assert pelvis.translation.z == pytest.approx(y)
                assert pelvis.translation.y == pytest.approx(-up)
            if channel.topic == "/scene" and k == steps - 1:
                scene = _decode(schema, message.data)
                muscles = next(e for e in scene.entities if e.id == "muscles")
                assert len(muscles.lines) == len(truth[k]["activations"])
                reds = [line.color.r for line in muscles.lines]
                np.testing.assert_allclose(reds, np.clip(truth[k]["activations"], 0, 1), atol=1e-6)
                assert all(len(line.points) >= 2 for line in muscles.lines)
                contacts = next(e for e in scene.entities if e.id == "contacts")
                assert len(contacts.spheres) == 4  # heel and toe spheres of each foot
        for topic in TOPICS:
            assert log_times[topic] == times, topic


def test_mcap_mujoco_walk(tmp_path: Path) -> None:
    env = MuscleEnv("walk-2d", backend="mujoco")
    truth = _record_by_hand(env, tmp_path / "walk.mcap", steps=50, seed=3)
    assert len(truth) >= 10 and truth[-1]["time"] > truth[0]["time"]
    _check_file(tmp_path / "walk.mcap", truth, "mujoco")


def test_mcap_opensim_walk(tmp_path: Path) -> None:
    env = MuscleEnv("walk-2d", backend="opensim")
    truth = _record_by_hand(env, tmp_path / "walk.mcap", steps=15, seed=4)
    assert len(truth) == 15
    _check_file(tmp_path / "walk.mcap", truth, "opensim")


def test_record_episode_summary(tmp_path: Path) -> None:
    env = MuscleEnv("walk-2d", backend="mujoco")
    rng = np.random.default_rng(0)
    summary = record_episode(
        env,
        lambda obs: rng.uniform(0.0, 1.0, env.action_space.shape[0]),
        tmp_path / "sub" / "episode.mcap",
        seed=1,
        metadata={"checkpoint": "sha256:feed"},
        max_steps=20,
    )
    assert summary["steps"] == 20 and summary["sim_time"] == pytest.approx(0.2)
    with open(summary["path"], "rb") as f:
        stats = make_reader(f).get_summary().statistics
    assert stats.message_count == 20 * len(TOPICS)


def test_a_z_up_body_stays_as_it_is(tmp_path: Path) -> None:
    env = MuscleEnv("walk-3d", backend="mujoco")  # MyoLeg: Z-up, X forward, like Foxglove
    summary = record_episode(
        env, lambda obs: np.zeros(80), tmp_path / "w.mcap", seed=0, max_steps=3
    )
    pelvis = env.sim.state().pelvis_pos
    with open(summary["path"], "rb") as f:
        *_, (schema, _, message) = make_reader(f).iter_messages(topics=["/tf"])
    tf = _decode(schema, message.data)
    got = next(t for t in tf.transforms if t.child_frame_id == "pelvis").translation
    np.testing.assert_allclose([got.x, got.y, got.z], pelvis)


def test_checkpoint_metadata_names_the_checkpoint(tmp_path: Path) -> None:
    state = {"w": torch.ones(3), "norm.mean": torch.zeros(3)}
    stage = {"index": 1, "name": "walk", "env_steps": 400}
    ckpt = save_checkpoint(tmp_path / "run", 1000, state, {"stage": stage})
    meta = checkpoint_metadata(ckpt)
    assert meta["checkpoint"] == str(ckpt) and json.loads(meta["stage"]) == stage
    assert meta["env_steps"] == "1000"
    assert len(meta["checkpoint_sha256"]) == 64 and len(meta["policy_sha256"]) == 64
    env = MuscleEnv("walk-2d", backend="mujoco")
    summary = record_episode(
        env, lambda obs: np.zeros(18), tmp_path / "e.mcap", seed=0, metadata=meta, max_steps=2
    )
    with open(summary["path"], "rb") as f:
        (record,) = list(make_reader(f).iter_metadata())
    assert record.metadata["checkpoint_sha256"] == meta["checkpoint_sha256"]


def test_opensim_replays_exactly_on_the_mujoco_model() -> None:
    env = MuscleEnv("obstacles-2d", backend="opensim")
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.full(18, 0.4))
    replay = MujocoReplay(env)
    replay.pose(env)
    want, got = env.sim.body_frames(), replay.sim.body_frames()
    assert set(want) == set(got)
    for name, frame in want.items():
        np.testing.assert_allclose(got[name].position, frame.position, atol=1e-9)
        assert abs(np.dot(got[name].quaternion, frame.quaternion)) == pytest.approx(1.0)
    want_paths, got_paths = env.sim.muscle_paths(), replay.sim.muscle_paths()
    for name, path in want_paths.items():  # origins and insertions (wrap points may differ)
        np.testing.assert_allclose(got_paths[name][[0, -1]], path[[0, -1]], atol=1e-9)
    np.testing.assert_allclose(replay.sim.obstacles(), env.sim.obstacles(), atol=1e-12)


needs_gl = pytest.mark.skipif(
    (reason := osmesa_available()) is not None,
    reason=f"no offscreen GL context (install Debian's libosmesa6): {reason}",
)


def _frames(path: Path) -> tuple[dict, list[bytes]]:
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    return meta, list(frames)


@needs_gl
def test_video_mujoco(tmp_path: Path) -> None:
    env = MuscleEnv("walk-2d", backend="mujoco")
    summary = record_video(
        env, lambda obs: np.full(18, 0.3), tmp_path / "walk.mp4", 0, 6, 96, 64, every=1
    )
    assert summary["steps"] == 6 and summary["frames"] == 7  # the reset pose, then each step
    meta, frames = _frames(tmp_path / "walk.mp4")
    assert tuple(meta["size"]) == (96, 64)
    assert meta["fps"] == pytest.approx(100.0)
    assert len(frames) == 7
    image = np.frombuffer(frames[-1], np.uint8).reshape(64, 96, 3)
    assert image.std() > 5  # something was drawn


@needs_gl
def test_video_and_mcap_of_an_opensim_episode(tmp_path: Path) -> None:
    env = MuscleEnv("walk-2d", backend="opensim")
    summary = record_episode(
        env,
        lambda obs: np.full(18, 0.3),
        tmp_path / "walk.mcap",
        seed=0,
        max_steps=4,
        video_path=tmp_path / "walk.mp4",
        video_size=(64, 48),
    )
    assert summary["steps"] == 4
    # 100 Hz control near 30 fps: one frame in 3 steps (reset pose, step 3)
    meta, frames = _frames(tmp_path / "walk.mp4")
    assert len(frames) == summary["frames"] == 2
    assert tuple(meta["size"]) == (64, 48)


def test_an_imitation_episode_records_its_reference(tmp_path: Path) -> None:
    from gaitforge.learner.evaluation.recording import IMITATION_TOPICS
    from gaitforge.learner.evaluation.reference_pose import ReferenceBody

    env = MuscleEnv("imitate-walk-2d", backend="mujoco")
    summary = record_episode(
        env, lambda obs: np.full(18, 0.15), tmp_path / "imitate.mcap", seed=5, max_steps=8
    )
    steps = summary["steps"]
    assert steps >= 3
    last_reference = ReferenceBody(env).frames(env)  # the pose of the last step
    assert last_reference is not None
    with open(summary["path"], "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary()
        counts = {
            c.topic: stats.statistics.channel_message_counts[c.id] for c in stats.channels.values()
        }
        assert counts == dict.fromkeys((*TOPICS, *IMITATION_TOPICS), steps)
        schema_ids = {c.topic: c.schema_id for c in stats.channels.values()}
        assert stats.schemas[schema_ids["/reference"]].name == "foxglove.SceneUpdate"
        messages = list(make_reader(f).iter_messages(topics=["/reference", "/imitation", "/tf"]))
    by_topic: dict[str, list] = {}
    for schema, channel, message in messages:
        by_topic.setdefault(channel.topic, []).append((schema, message))
    phases = [json.loads(m.data)["phase"] for _, m in by_topic["/imitation"]]
    assert all(0.0 <= p < 1.0 for p in phases) and len(set(phases)) == steps
    schema, message = by_topic["/reference"][-1]
    (entity,) = _decode(schema, message.data).entities
    assert entity.id == "reference" and entity.frame_id == "world"
    assert 0.0 < entity.spheres[0].color.a < 1.0  # translucent
    assert len(entity.spheres) == len(last_reference) and entity.lines
    # the reference pelvis stands where the body's is along the ground (Y-up to Z-up)
    pelvis = last_reference["pelvis"].position
    schema, message = by_topic["/tf"][-1]
    body = next(t for t in _decode(schema, message.data).transforms if t.child_frame_id == "pelvis")
    assert body.translation.x == pytest.approx(pelvis[0])
    centres = [(s.pose.position.x, s.pose.position.z) for s in entity.spheres]
    assert (pytest.approx(pelvis[0]), pytest.approx(pelvis[1])) in centres


@needs_gl
def test_an_imitation_video_draws_the_reference(tmp_path: Path) -> None:
    from gaitforge.learner.evaluation.video import VideoRecorder

    env = MuscleEnv("imitate-walk-2d", backend="mujoco")
    summary = record_video(
        env, lambda obs: np.full(18, 0.15), tmp_path / "imitate.mp4", 3, 4, 96, 64, every=1
    )
    assert summary["frames"] == summary["steps"] + 1
    _, frames = _frames(tmp_path / "imitate.mp4")
    assert len(frames) == summary["frames"]
    # the same pose without the reference differs where the green skeleton was drawn
    with VideoRecorder(tmp_path / "x.mp4", env, 96, 64) as video:
        with_reference = video.render(env)
        video.reference.visible = False  # the body alone
        alone = video.render(env)
    assert np.abs(with_reference.astype(int) - alone.astype(int)).sum() > 0
    greener = with_reference[..., 1].astype(int) - alone[..., 1].astype(int)
    assert greener.max() > 20
