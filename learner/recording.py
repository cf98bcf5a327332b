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

Frames: Foxglove is Z-up. Poses, paths and obstacles are rotated from the simulator's world
(gait2d and OpenSim bodies are Y-up with X forward; MyoLeg is Z-up with X forward) into a
Z-up, X-forward ``world`` frame, so that both stand upright in the 3D panel.

A metadata record ``gaitforge`` holds scene, backend, profile, body, control rate and what the
caller adds (checkpoint hash, stage, ...). The writer is foxglove-sdk's (a ``Context`` per
recorder, so recorders in one process never see each other's channels).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from collections.abc import Mapping
from contextlib import ExitStack
from pathlib import Path
from types import TracebackType
from typing import Any

import foxglove
import numpy as np
from foxglove.channels import FrameTransformsChannel, JointStatesChannel, SceneUpdateChannel
from foxglove.messages import (
    Color,
    FrameTransform,
    FrameTransforms,
    JointState,
    JointStates,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)
from gaitforge.learner.checkpoint_meta import META_FILE, read_meta
from gaitforge.workers.env import GRAVITY, MuscleEnv
from gaitforge.workers.episode import Act, EpisodeObserver, EpisodeSummary, run_episode
from gaitforge.workers.rewards import TERMS
from gaitforge.workers.sim.base import HEALTHY, SimState

logger = logging.getLogger(__name__)

WORLD = "world"
METADATA_NAME = "gaitforge"
TOPIC_TF = "/tf"
TOPIC_SCENE = "/scene"
TOPIC_JOINTS = "/joints"
SCALAR_TOPICS = ("/reward", "/speed", "/activations", "/excitations", "/foot_forces", "/health")
TOPICS = (TOPIC_TF, TOPIC_SCENE, TOPIC_JOINTS, *SCALAR_TOPICS)
"""Every channel a recording has, one message each per step."""

BODY_RADIUS = 0.03
"""m: the sphere drawn at each body origin."""
BONE_WIDTH = 0.015
"""m: the line from a parent body's origin to its child's."""
MUSCLE_WIDTH = 0.008
"""m: the muscle lines."""


# ---- frames -----------------------------------------------------------------------------------


def z_up_rotation(up_axis: int, forward_axis: int) -> np.ndarray:
    """[3, 3] rotation taking the simulator's world (``up_axis``, ``forward_axis``) to a
    Z-up, X-forward frame (Y = Z x X, to the left): rows are the new axes in the old frame."""
    up, forward = np.eye(3)[up_axis], np.eye(3)[forward_axis]
    return np.stack([forward, np.cross(up, forward), up])


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """[4] unit quaternion (w, x, y, z) of the rotation matrix ``r`` [3, 3]."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of two (w, x, y, z) quaternions: rotation ``b`` then ``a``."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def activation_color(a: float, alpha: float = 1.0) -> Color:
    """Blue (activation 0) to red (1), through purple."""
    a = float(np.clip(a, 0.0, 1.0)) if np.isfinite(a) else 0.0
    return Color(r=a, g=0.1, b=1.0 - a, a=alpha)


def _ns(seconds: float) -> int:
    return max(0, round(seconds * 1e9))


def _point(p: np.ndarray) -> Point3:
    return Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _pose(p: np.ndarray) -> Pose:
    return Pose(
        position=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )


def _maybe_float(x: float | None) -> float | None:
    return None if x is None else float(x)


def _json_schema(title: str, numbers: list[str], strings: tuple[str, ...] = ()) -> dict:
    props: dict[str, dict[str, str]] = {name: {"type": "number"} for name in numbers}
    props.update({name: {"type": "string"} for name in strings})
    return {"title": title, "type": "object", "properties": props}


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


class EpisodeRecorder:
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
        sim = env.sim
        self.steps = 0
        self._closed = False
        self._last_time = 0.0
        self._dt = env.dt
        self._muscles = list(sim.muscle_names)
        self._feet = list(sim.foot_names)
        self._forward, self._up = sim.forward_axis, sim.up_axis
        self._rot = z_up_rotation(sim.up_axis, sim.forward_axis)
        self._rot_q = matrix_to_quat(self._rot)
        self._target_speed = float(env.scene.task.target_speed or 0.0)
        self._weight = max(GRAVITY * sim.report.mass, 1e-9)
        self._start_forward: float | None = None
        self._context = foxglove.Context()
        self._writer = foxglove.open_mcap(self.path, allow_overwrite=True, context=self._context)
        ctx = self._context
        self._tf = FrameTransformsChannel(TOPIC_TF, context=ctx)
        self._scene = SceneUpdateChannel(TOPIC_SCENE, context=ctx)
        self._joints = JointStatesChannel(TOPIC_JOINTS, context=ctx)
        schemas = {
            "/reward": _json_schema("gaitforge.Reward", ["total", *TERMS]),
            "/speed": _json_schema(
                "gaitforge.Speed", ["forward", "target", "distance", "pelvis_height"]
            ),
            "/activations": _json_schema("gaitforge.Activations", self._muscles),
            "/excitations": _json_schema("gaitforge.Excitations", self._muscles),
            "/foot_forces": _json_schema("gaitforge.FootForces", self._feet),
            "/health": _json_schema("gaitforge.Health", ["ok", "fell", "step"], ("cause",)),
        }
        self._scalars = {
            topic: foxglove.Channel(topic, schema=schema, context=ctx)
            for topic, schema in schemas.items()
        }
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
        log_time = _ns(t)
        if finite:
            self._log_geometry(env, state, log_time)
        self._log_scalars(state if finite else None, action, terms, info, log_time)
        self.steps += 1

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Episode observer (``workers.episode``): nothing is logged at reset."""

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

    def on_end(self, summary: EpisodeSummary | None) -> None:
        """Episode observer: :meth:`close`."""
        self.close()

    def close(self) -> None:
        """Finish the file (summary, index); idempotent."""
        if not self._closed:
            self._closed = True
            self._writer.close()
            for channel in (self._tf, self._scene, self._joints, *self._scalars.values()):
                channel.close()
            logger.info("recording: %d steps to %s", self.steps, self.path)

    def __enter__(self) -> EpisodeRecorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

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
            "muscles": json.dumps(self._muscles),
            "source_up_axis": "xyz"[self._up],
            "source_forward_axis": "xyz"[self._forward],
            "log_time": "simulated time since reset, ns",
        }
        meta.update({str(k): str(v) for k, v in extra.items()})
        return meta

    def _to_world(self, p: np.ndarray) -> np.ndarray:
        """[..., 3] simulator-world points to the Z-up ``world`` frame."""
        return np.asarray(p) @ self._rot.T

    def _log_geometry(self, env: MuscleEnv, state: SimState, log_time: int) -> None:
        sim = env.sim
        stamp = Timestamp(log_time // 10**9, log_time % 10**9)
        frames = sim.body_frames()
        positions = {name: self._to_world(f.position) for name, f in frames.items()}
        transforms = []
        for name, frame in frames.items():
            q = quat_multiply(self._rot_q, frame.quaternion)
            transforms.append(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=WORLD,
                    child_frame_id=name,
                    translation=Vector3(
                        x=float(positions[name][0]),
                        y=float(positions[name][1]),
                        z=float(positions[name][2]),
                    ),
                    rotation=Quaternion(w=float(q[0]), x=float(q[1]), y=float(q[2]), z=float(q[3])),
                )
            )
        self._tf.log(FrameTransforms(transforms=transforms), log_time=log_time)

        grey = Color(r=0.8, g=0.8, b=0.8, a=1.0)
        spheres = [
            SpherePrimitive(
                pose=_pose(p),
                size=Vector3(x=2 * BODY_RADIUS, y=2 * BODY_RADIUS, z=2 * BODY_RADIUS),
                color=grey,
            )
            for p in positions.values()
        ]
        bones = [
            point
            for name, frame in frames.items()
            if frame.parent in positions
            for point in (_point(positions[frame.parent]), _point(positions[name]))
        ]
        skeleton = SceneEntity(
            timestamp=stamp,
            frame_id=WORLD,
            id="skeleton",
            spheres=spheres,
            lines=[
                LinePrimitive(
                    type=LinePrimitiveLineType.LineList,
                    thickness=BONE_WIDTH,
                    points=bones,
                    color=grey,
                )
            ]
            if bones
            else [],
        )
        paths = sim.muscle_paths()
        lines = []
        for name, a in zip(self._muscles, state.activations, strict=True):
            path = paths.get(name)
            if path is None or len(path) < 2:
                continue
            lines.append(
                LinePrimitive(
                    type=LinePrimitiveLineType.LineStrip,
                    thickness=MUSCLE_WIDTH,
                    points=[_point(p) for p in self._to_world(path)],
                    color=activation_color(a),
                )
            )
        muscles = SceneEntity(timestamp=stamp, frame_id=WORLD, id="muscles", lines=lines)
        obstacle_spheres = []
        for ahead, height, radius in sim.obstacles():
            centre = np.zeros(3)
            centre[self._forward], centre[self._up] = ahead, height
            obstacle_spheres.append(
                SpherePrimitive(
                    pose=_pose(self._to_world(centre)),
                    size=Vector3(x=2 * radius, y=2 * radius, z=2 * radius),
                    color=Color(r=0.6, g=0.4, b=0.3, a=1.0),
                )
            )
        obstacles = SceneEntity(
            timestamp=stamp, frame_id=WORLD, id="obstacles", spheres=obstacle_spheres
        )
        contact_spheres = []
        forces = dict(zip(self._feet, state.foot_forces, strict=True))
        for foot, spheres in sim.contact_spheres().items():
            load = float(np.clip(forces.get(foot, 0.0) / self._weight, 0.0, 1.0))
            colour = Color(r=0.5 * (1 - load), g=0.5 + 0.5 * load, b=0.5 * (1 - load), a=0.8)
            for *centre, radius in spheres:
                contact_spheres.append(
                    SpherePrimitive(
                        pose=_pose(self._to_world(np.array(centre))),
                        size=Vector3(x=2 * radius, y=2 * radius, z=2 * radius),
                        color=colour,
                    )
                )
        contacts = SceneEntity(
            timestamp=stamp, frame_id=WORLD, id="contacts", spheres=contact_spheres
        )
        self._scene.log(
            SceneUpdate(entities=[skeleton, muscles, obstacles, contacts]), log_time=log_time
        )

        coords = sim.coordinates()
        speeds = dict(zip(sim.dof_names, state.dof_vel, strict=True))
        self._joints.log(
            JointStates(
                timestamp=stamp,
                joints=[
                    JointState(
                        name=name, position=float(q), velocity=_maybe_float(speeds.get(name))
                    )
                    for name, q in coords.items()
                ],
            ),
            log_time=log_time,
        )

    def _log_scalars(
        self,
        state: SimState | None,
        action: np.ndarray,
        terms: dict[str, float],
        info: dict[str, Any],
        log_time: int,
    ) -> None:
        reward = {"total": float(sum(terms.values())), **{k: float(v) for k, v in terms.items()}}
        self._scalars["/reward"].log(reward, log_time=log_time)
        action = np.asarray(action, dtype=float).ravel()
        self._scalars["/excitations"].log(
            {m: float(e) for m, e in zip(self._muscles, action, strict=False)}, log_time=log_time
        )
        if state is not None:
            here = float(state.pelvis_pos[self._forward])
            if self._start_forward is None:
                self._start_forward = here - float(info.get("distance", 0.0))
            speed = {
                "forward": float(state.pelvis_vel[self._forward]),
                "target": self._target_speed,
                "distance": float(info.get("distance", here - self._start_forward)),
                "pelvis_height": float(state.pelvis_pos[self._up]),
            }
            activations = dict(zip(self._muscles, map(float, state.activations), strict=True))
            forces = dict(zip(self._feet, map(float, state.foot_forces), strict=True))
        else:  # a failed step: no trustworthy state, keep the channels' counts
            speed = {"target": self._target_speed, "distance": float(info.get("distance", 0.0))}
            activations, forces = {}, {}
        self._scalars["/speed"].log(speed, log_time=log_time)
        self._scalars["/activations"].log(activations, log_time=log_time)
        self._scalars["/foot_forces"].log(forces, log_time=log_time)
        cause = str(info.get("health", HEALTHY))
        health = {
            "ok": int(cause == HEALTHY),
            "cause": cause,
            "fell": int(bool(info.get("fell", False))),
            "step": int(info.get("step", self.steps + 1)),
        }
        self._scalars["/health"].log(health, log_time=log_time)


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
    (width, height ``video_size`` pixels; see :mod:`learner.video`). Either may be None.

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
            from gaitforge.learner.video import VideoRecorder  # lazy: needs a GL context

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
