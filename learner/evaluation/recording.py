"""Episode recordings: MCAP files with Foxglove's well-known schemas, for Foxglove or Lichtblick.

One file per episode, one message per channel per control step, log time = simulated time
(ns since the episode's reset). Channels:

=================  ==========================  ===================================================
topic              schema (encoding)           content
=================  ==========================  ===================================================
``/tf``            foxglove.FrameTransforms    world pose of every body: parent ``world``, child
                   (protobuf)                  the body's name; translation m, rotation unit quat
``/scene``         foxglove.SceneUpdate        entities in frame ``world``: ``skeleton`` (a sphere
                   (protobuf)                  per body origin, lines parent to child), ``muscles``
                                               (one line strip per muscle path, blue at activation
                                               0 to red at 1), ``obstacles`` (spheres),
                                               ``contacts`` (foot contact spheres, grey unloaded
                                               to green at body weight on that foot)
``/joints``        foxglove.JointStates        every scalar joint coordinate: position rad or m,
                   (protobuf)                  velocity of the kept dofs rad/s or m/s
``/reward``        gaitforge.Reward (json)     ``total`` and every weighted reward term
``/speed``         gaitforge.Speed (json)      ``forward`` pelvis speed and ``target`` m/s,
                                               ``distance`` since reset m, ``pelvis_height`` m
``/activations``   gaitforge.Activations       muscle activation by muscle name, in [0, 1]
``/excitations``   gaitforge.Excitations       the action: excitation by muscle name, in [0, 1]
``/foot_forces``   gaitforge.FootForces        normal ground reaction per foot, N
``/health``        gaitforge.Health (json)     ``ok`` (1/0), ``cause``, ``fell`` (1/0), ``step``
=================  ==========================  ===================================================

Scenes with the gait clock (``task.clock``) add ``/reference``, and imitation scenes
(``task.imitate``) ``/imitation``, one message each per step:

=================  ==========================  ===================================================
``/reference``     foxglove.SceneUpdate        entity ``reference`` in frame ``world``: the
                   (protobuf)                  reference pose (``env.reference_state()``) as a
                                               translucent green skeleton on a second copy of
                                               the body's kinematics, moved with the body's
                                               pelvis along the ground (``reference_pose``)
``/imitation``     gaitforge.Imitation (json)  ``phase`` [0, 1), ``pose_error_rad`` (RMS over the
                                               tracked kept joints), ``kept`` (1/0)
=================  ==========================  ===================================================

In Foxglove's 3D panel the reference is a topic of its own, shown or hidden beside
``/scene``; ``/imitation`` plots the tracking error over the episode.

Frames: Foxglove is Z-up. Poses, paths and obstacles are rotated from the simulator's world
(gait2d and OpenSim bodies are Y-up with X forward; MyoLeg is Z-up with X forward) into a
Z-up, X-forward ``world`` frame, so that both stand upright in the 3D panel. The messages are
built by ``learner.evaluation.recording_messages``; this module writes them.

A metadata record ``gaitforge`` holds scene, backend, profile, body, control rate and what the
caller adds (checkpoint hash, stage, ...). The writer is foxglove-sdk's (a ``Context`` per
recorder, so recorders in one process never see each other's channels).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Mapping
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
from foxglove.channels import FrameTransformsChannel, JointStatesChannel, SceneUpdateChannel
from foxglove.messages import Timestamp
from gaitforge.learner.checkpoint_meta import META_FILE, read_meta
from gaitforge.learner.evaluation.recording_messages import EpisodeMessages
from gaitforge.learner.evaluation.reference_pose import ReferenceBody, has_clock
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.episode import (
    Act,
    ClosingObserver,
    EpisodeObserver,
    run_episode,
)

logger = logging.getLogger(__name__)

METADATA_NAME = "gaitforge"
TOPIC_TF = "/tf"
TOPIC_SCENE = "/scene"
TOPIC_JOINTS = "/joints"
SCALAR_TOPICS = ("/reward", "/speed", "/activations", "/excitations", "/foot_forces", "/health")
TOPICS = (TOPIC_TF, TOPIC_SCENE, TOPIC_JOINTS, *SCALAR_TOPICS)
"""Every channel a recording has, one message each per step."""
TOPIC_REFERENCE = "/reference"
TOPIC_IMITATION = "/imitation"
IMITATION_TOPICS = (TOPIC_REFERENCE, TOPIC_IMITATION)
"""The channels imitation scenes add, one message each per step (a clock alone adds the
first)."""


def checkpoint_metadata(path: str | os.PathLike[str]) -> dict[str, str]:
    """Recording metadata naming a checkpoint directory (``learner.checkpoint`` layout):
    ``checkpoint`` (its path), ``checkpoint_sha256`` (sha256 of its ``manifest.json``, which
    holds the sha256 of every file: one hash for the whole checkpoint), ``policy_sha256``, and
    ``stage`` (JSON), ``env_steps`` from ``meta.json`` when there
    (``learner.checkpoint_meta.read_meta``). Reads JSON only, unpickles nothing; a missing
    manifest raises ``FileNotFoundError`` naming it."""
    root = Path(path)
    manifest_bytes = (root / "manifest.json").read_bytes()
    manifest = json.loads(manifest_bytes)
    out = {
        "checkpoint": str(root),
        "checkpoint_sha256": hashlib.sha256(manifest_bytes).hexdigest(),
        "policy_sha256": str(manifest.get("policy.safetensors", "")),
    }
    if (root / META_FILE).exists():
        meta = read_meta(root)
        if meta.stage is not None:
            out["stage"] = json.dumps(meta.stage.model_dump(mode="json"), sort_keys=True)
        out["env_steps"] = str(meta.env_steps)
    return out


# ---- recorder ---------------------------------------------------------------------------------


class EpisodeRecorder(ClosingObserver):
    """Writes one episode of ``env`` to an MCAP file at ``path``.

    An episode observer (``workers.episode``); or by hand: call :meth:`log_step` after every
    ``env.step`` (it reads the simulator directly, so call it before the next ``step`` or
    ``reset``), then :meth:`close`, or use it as a context manager. ``metadata`` (strings;
    e.g. ``{"checkpoint": sha256, "stage": "walk"}``) goes into the ``gaitforge`` metadata
    record beside scene, backend, profile, body and rates.
    An existing file at ``path`` is overwritten; parent directories are created.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        env: MuscleEnv,
        metadata: Mapping[str, str] | None = None,
    ) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.steps = 0
        self._closed = False
        self._last_time = 0.0
        self._dt = env.dt
        self._messages = EpisodeMessages(env)
        self._context = foxglove.Context()
        self._writer = foxglove.open_mcap(self.path, allow_overwrite=True, context=self._context)
        ctx = self._context
        self._tf = FrameTransformsChannel(TOPIC_TF, context=ctx)
        self._scene = SceneUpdateChannel(TOPIC_SCENE, context=ctx)
        self._joints = JointStatesChannel(TOPIC_JOINTS, context=ctx)
        self._scalars = {
            topic: foxglove.Channel(topic, schema=schema, context=ctx)
            for topic, schema in self._messages.scalar_schemas().items()
        }
        self._reference: ReferenceBody | None = None
        self._reference_channel: SceneUpdateChannel | None = None
        self._imitation_channel: foxglove.Channel | None = None
        if has_clock(env):
            try:
                self._reference = ReferenceBody(env)
            except ValueError as exc:
                logger.warning("recording %s: no reference skeleton: %s", self.path, exc)
            self._reference_channel = SceneUpdateChannel(TOPIC_REFERENCE, context=ctx)
        if env.imitation is not None:
            schema = self._messages.imitation_schema()
            self._imitation_channel = foxglove.Channel(TOPIC_IMITATION, schema=schema, context=ctx)
        self._writer.write_metadata(METADATA_NAME, self._metadata(env, metadata or {}))

    # ---- public -----------------------------------------------------------------------------

    def log_step(
        self,
        env: MuscleEnv,
        action: np.ndarray,
        reward_terms: Mapping[str, float] | None = None,
        info: Mapping[str, Any] | None = None,
    ) -> None:
        """Record the state after one ``env.step(action)``.

        Args:
            env: the environment just stepped (the one given to the constructor).
            action: [n_muscles] excitations sent, in [0, 1].
            reward_terms: weighted reward terms of the step; default ``info["reward_terms"]``.
            info: the step's info dict (``health``, ``fell``, ``distance``, ``step``).
        """
        if self._closed:
            raise RuntimeError(f"recording {self.path} is closed")
        info = dict(info or {})
        terms = dict(reward_terms if reward_terms is not None else info.get("reward_terms", {}))
        state = env.sim.state()
        finite = state.is_finite()
        t = state.time if finite else self._last_time + self._dt
        self._last_time = t
        log_time = max(0, round(t * 1e9))
        if finite:
            stamp = Timestamp(log_time // 10**9, log_time % 10**9)
            tf, scene, joints = self._messages.geometry(env.sim, state, stamp)
            self._tf.log(tf, log_time=log_time)
            self._scene.log(scene, log_time=log_time)
            self._joints.log(joints, log_time=log_time)
        scalars = self._messages.scalars(
            state if finite else None, action, terms, info, self.steps + 1
        )
        for topic, message in scalars.items():
            self._scalars[topic].log(message, log_time=log_time)
        if self._reference_channel is not None:
            frames = None if self._reference is None else self._reference.frames(env)
            stamp = Timestamp(log_time // 10**9, log_time % 10**9)
            message = self._messages.reference(frames or {}, stamp)
            self._reference_channel.log(message, log_time=log_time)
        if self._imitation_channel is not None:
            self._imitation_channel.log(self._messages.imitation(info), log_time=log_time)
        self.steps += 1

    def on_step(
        self,
        env: MuscleEnv,
        action: np.ndarray,
        obs: np.ndarray,
        reward: float,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> None:
        """Episode observer: :meth:`log_step` with the step's reward terms."""
        self.log_step(env, action, info.get("reward_terms"), info)

    def close(self) -> None:
        """Finish the file (summary, index); idempotent."""
        if not self._closed:
            self._closed = True
            self._writer.close()
            channels = (
                self._tf,
                self._scene,
                self._joints,
                *self._scalars.values(),
                self._reference_channel,
                self._imitation_channel,
            )
            for channel in channels:
                if channel is not None:
                    channel.close()
            logger.info("recording: %d steps to %s", self.steps, self.path)

    # ---- helpers ----------------------------------------------------------------------------

    def _metadata(self, env: MuscleEnv, extra: Mapping[str, str]) -> dict[str, str]:
        scene = env.scene
        meta = {
            "scene": scene.name,
            "backend": env.backend,
            "profile": scene.profile_name(env.backend),
            "profile_detail": env.sim.report.profile.model_dump_json(),
            "body": scene.body,
            "control_hz": str(scene.control_hz),
            "muscles": json.dumps(self._messages.muscles),
            "source_up_axis": "xyz"[self._messages.up],
            "source_forward_axis": "xyz"[self._messages.forward],
            "log_time": "simulated time since reset, ns",
        }
        meta.update({str(k): str(v) for k, v in extra.items()})
        return meta


def record_episode(
    env: MuscleEnv,
    act_fn: Act,
    path: str | os.PathLike[str] | None,
    seed: int,
    metadata: Mapping[str, str] | None = None,
    max_steps: int | None = None,
    video_path: str | os.PathLike[str] | None = None,
    video_size: tuple[int, int] = (640, 480),
) -> dict[str, Any]:
    """One episode of ``act_fn`` (observation [n_obs] -> excitations [n_muscles] in [0, 1])
    on ``env`` from ``env.reset(seed=seed)`` (``workers.episode.run_episode``) until it ends
    or ``max_steps``, recorded to the MCAP ``path`` and/or rendered to the MP4 ``video_path``
    (width, height ``video_size`` pixels; see :mod:`learner.evaluation.video`). Either may be None.

    Returns a summary: ``path``, ``video_path``, ``steps``, ``frames`` (video frames),
    ``sim_time`` (s), ``return`` (sum of rewards), ``distance`` (m), ``fell``, ``health``
    (cause of the last step), ``terminated``, ``truncated``.
    """
    observers: list[EpisodeObserver] = []
    video = None
    with ExitStack() as stack:  # closes what was opened if a later one fails to open
        if path is not None:
            observers.append(stack.enter_context(EpisodeRecorder(path, env, metadata)))
        if video_path is not None:
            from gaitforge.learner.evaluation.video import VideoRecorder  # lazy: needs a GL context

            video = stack.enter_context(VideoRecorder(video_path, env, *video_size))
            observers.append(video)
        summary = run_episode(env, act_fn, seed, observers, max_steps)
    return {
        "path": None if path is None else str(path),
        "video_path": None if video_path is None else str(video_path),
        "frames": 0 if video is None else video.frames,
        "steps": summary.steps,
        "sim_time": summary.sim_time_s,
        "return": summary.return_,
        "distance": summary.distance_m,
        "fell": summary.fell,
        "health": summary.health,
        "terminated": summary.terminated,
        "truncated": summary.truncated,
    }
