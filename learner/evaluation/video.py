"""MP4 videos of episodes, rendered offscreen on the CPU with MuJoCo (``mujoco.Renderer``)
and OSMesa.

Rendering needs Debian's ``libosmesa6`` (``make`` installs it where apt-get exists) and
``MUJOCO_GL=osmesa``, the default here: the renderer is handed an OSMesa context class, since
``mujoco`` picks its default context class once, when it is imported (long before this module,
by the simulators), and ``MUJOCO_GL`` is set (``os.environ.setdefault``) once that worked.
Set ``MUJOCO_GL=egl`` (a GPU) or ``glfw`` before starting the process to use those instead.
Frames go to ffmpeg (bundled by ``imageio-ffmpeg``) as H.264, yuv420p.

The camera tracks the pelvis from the body's side (the lateral axis, so a sagittal gait is
seen in profile) with the body's up axis up, at a fixed height; stripes on the floor every
0.5 m show progress. Muscles (MuJoCo tendons) are coloured by activation, blue at 0 to red
at 1, and a skeleton (a sphere per body origin, capsules parent to child) is
drawn over the model, since pruned scenes keep no visual geoms. In imitation scenes the
reference pose is drawn too, a translucent green copy of the skeleton overlaid in place and
moved with the pelvis along the ground (``learner.evaluation.video_reference``).

OpenSim episodes are rendered by replaying the OpenSim coordinates (by name), activations
and obstacles on the MuJoCo model of the same scene, which shares the body's coordinate
names; a scene without a MuJoCo backend cannot be rendered.
"""

from __future__ import annotations

import importlib
import logging
import os
from pathlib import Path
from typing import Any

import imageio_ffmpeg
import mujoco
import numpy as np
from gaitforge.learner.evaluation.video_reference import (
    ReferenceSkeleton,
    add_geom,
    add_model_skeleton,
)
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.episode import Act, ClosingObserver, run_episode
from gaitforge.workers.sim.mujoco.compile import OBSTACLE_PREFIX
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

logger = logging.getLogger(__name__)

TARGET_FPS = 30.0
"""Frames per second aimed at when ``every`` is not given (one frame per control step at most)."""
STRIPE_SPACING = 0.5
"""m between floor stripes."""


def _renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A ``mujoco.Renderer`` on a GL context of ``MUJOCO_GL``'s kind, OSMesa by default.

    ``mujoco.Renderer`` takes its context class from ``MUJOCO_GL`` as it was when ``mujoco``
    was imported (by the simulators, long before this), so the class is handed to it here.
    ``MUJOCO_GL`` is then set (``setdefault``), only once a context was made, so that a
    machine without OSMesa never hands the setting to child processes (whose
    ``import mujoco`` would then try to load OSMesa)."""
    backend = (os.environ.get("MUJOCO_GL") or "osmesa").lower()
    gl_context = importlib.import_module(mujoco.Renderer.__module__).gl_context
    default = gl_context.GLContext
    try:
        if backend == "osmesa":
            from mujoco.osmesa import GLContext  # sets PYOPENGL_PLATFORM=osmesa if unset
        elif backend == "egl":
            from mujoco.egl import GLContext  # type: ignore[no-redef]
        else:
            from mujoco.glfw import GLContext  # type: ignore[no-redef]
        gl_context.GLContext = GLContext
        room = max(1000, 4 * model.ngeom + 4 * model.nbody + 200)  # + tendons, skeleton
        renderer = mujoco.Renderer(model, height, width, max_geom=room)
    except Exception as exc:
        raise RuntimeError(
            f"cannot create a {backend} GL context for offscreen rendering "
            f"({type(exc).__name__}: {exc}); on Debian: apt-get install -y libosmesa6"
        ) from exc
    finally:
        gl_context.GLContext = default
    os.environ.setdefault("MUJOCO_GL", backend)
    return renderer


def osmesa_available() -> str | None:
    """None when offscreen rendering works here, else why not (for test skips, messages)."""
    try:
        _renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 16, 16).close()
    except RuntimeError as exc:
        return str(exc)
    return None


class MujocoReplay:
    """The MuJoCo model of an OpenSim env's scene (``.sim``, a :class:`MujocoSimulator`),
    posed by :meth:`pose` from the OpenSim simulator's coordinates (by name), activations and
    obstacles. Same body, same kinematics: body poses and muscle paths agree to rounding."""

    def __init__(self, env: MuscleEnv) -> None:
        if "mujoco" not in env.scene.backends:
            raise ValueError(
                f"scene {env.scene.name!r} has no MuJoCo model of its body "
                f"(backends {env.scene.backends}): its {env.backend} episodes cannot be rendered"
            )
        self.sim = MujocoSimulator(env.scene)
        m = self.sim.model
        self._qadr = {m.joint(j).name: int(m.jnt_qposadr[j]) for j in range(m.njnt)}
        self._actadr = {m.actuator(i).name: int(m.actuator_actadr[i]) for i in range(m.nu)}
        self._obstacles = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{OBSTACLE_PREFIX}{i}")
            for i in range(self.sim.report.plan.obstacles)
        ]
        self._warned = False

    def pose(self, env: MuscleEnv) -> None:
        """Copy the state of ``env`` (an OpenSim env) onto ``self.sim`` (positions only)."""
        m, d = self.sim.model, self.sim.data
        coords = env.sim.coordinates()
        missing = [name for name in coords if name not in self._qadr]
        if missing and not self._warned:
            logger.warning("video replay: coordinates missing in the MuJoCo model: %s", missing)
            self._warned = True
        for name, value in coords.items():
            if name in self._qadr:
                d.qpos[self._qadr[name]] = value
        state = env.sim.state()
        for name, a in zip(env.sim.muscle_names, state.activations, strict=True):
            adr = self._actadr.get(name, -1)
            if adr >= 0:
                d.act[adr] = a
        up, forward = self.sim.up_axis, self.sim.forward_axis
        for gid, (ahead, height, radius) in zip(self._obstacles, env.sim.obstacles(), strict=False):
            m.geom_pos[gid] = 0.0
            m.geom_pos[gid, forward], m.geom_pos[gid, up] = ahead, height
            m.geom_size[gid, 0] = radius
        d.time = state.time
        mujoco.mj_fwdPosition(m, d)


class FrameRenderer:
    """Images of an env's state, offscreen: a side camera tracking the pelvis, muscles coloured
    by activation, the skeleton and, with a gait clock, the reference pose's.

    Args:
        env: a MuJoCo env, or an OpenSim env of a scene that also runs on MuJoCo.
        width, height: pixels; rounded down to even numbers (H.264, yuv420p).
        distance: m from the camera to the tracked point.
        antialias: multisampling, shadows and reflections (about 3 times slower on a CPU).
    """

    def __init__(
        self,
        env: MuscleEnv,
        width: int = 640,
        height: int = 480,
        distance: float = 2.5,
        antialias: bool = False,
    ) -> None:
        self.width, self.height = max(2, width - width % 2), max(2, height - height % 2)
        self._distance = distance
        self._replay = MujocoReplay(env) if env.backend != "mujoco" else None
        sim = self._replay.sim if self._replay else env.sim
        self._model: mujoco.MjModel = sim.model
        self._data: mujoco.MjData = sim.data
        self._up, self._forward = sim.up_axis, sim.forward_axis
        m = self._model
        self._pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        m.vis.global_.offwidth = max(m.vis.global_.offwidth, self.width)
        m.vis.global_.offheight = max(m.vis.global_.offheight, self.height)
        if not antialias:  # multisampling triples the time of a software-rendered frame
            m.vis.quality.offsamples = 0
        self._renderer = _renderer(m, self.width, self.height)
        self._scene = self._renderer.scene
        self._option = mujoco.MjvOption()
        self._option.flags[mujoco.mjtVisFlag.mjVIS_TENDON] = 1
        self._option.geomgroup[:4] = 1
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(antialias)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = int(antialias)
        self._tendon_act = np.full(m.ntendon, -1, dtype=int)
        for i in range(m.nu):
            if int(m.actuator_trntype[i]) == int(mujoco.mjtTrn.mjTRN_TENDON):
                self._tendon_act[m.actuator_trnid[i, 0]] = m.actuator_actadr[i]
        self._camera = mujoco.MjvCamera()
        if m.nlight == 0:  # bodies built from neutral specs have no lights: a brighter headlight
            m.vis.headlight.ambient[:] = 0.45
            m.vis.headlight.diffuse[:] = 0.7
        self.reference = ReferenceSkeleton(env)
        """the reference pose's skeleton (scenes with a gait clock)"""
        self._closed = False

    def render(self, env: MuscleEnv) -> np.ndarray:
        """[height, width, 3] uint8 RGB image of the env's current state."""
        if self._replay is not None:
            self._replay.pose(env)
        self._renderer.update_scene(self._data, self._camera, self._option)
        self._colour_tendons()
        target = self._target()
        self._place_camera(target)
        if self._pelvis >= 0:  # locomotion: progress along the floor
            self._add_floor_stripes(target)
        add_model_skeleton(self._scene, self._model, self._data)
        self.reference.draw(self._scene, env)
        return self._renderer.render()

    def close(self) -> None:
        """Free the GL resources; idempotent."""
        if not self._closed:
            self._closed = True
            self._renderer.close()

    def _target(self) -> np.ndarray:
        """[3] tracked point: the pelvis along the ground, at a fixed height (m)."""
        m, d = self._model, self._data
        if self._pelvis < 0:
            return np.asarray(m.stat.center, dtype=float).copy()
        target = d.xpos[self._pelvis].copy()
        target[self._up] = 0.8
        return target

    def _colour_tendons(self) -> None:
        """Muscle tendons blue (activation 0) to red (1), as in the MCAP recordings."""
        scene, act = self._scene, self._data.act
        tendon = int(mujoco.mjtObj.mjOBJ_TENDON)
        for k in range(scene.ngeom):
            geom = scene.geoms[k]
            if geom.objtype == tendon and self._tendon_act[geom.objid] >= 0:
                a = float(np.clip(act[self._tendon_act[geom.objid]], 0.0, 1.0))
                geom.rgba[:] = (a, 0.1, 1.0 - a, 1.0)

    def _place_camera(self, target: np.ndarray) -> None:
        up = np.eye(3)[self._up]
        forward = np.eye(3)[self._forward]
        side = np.cross(forward, up)  # the body's left in a Y-up world, its right in Z-up
        eye = target + self._distance * side + 0.15 * self._distance * up
        look = target - eye
        look /= np.linalg.norm(look)
        cam_up = up - np.dot(up, look) * look
        cam_up /= np.linalg.norm(cam_up)
        for cam in self._scene.camera:
            cam.pos[:] = eye
            cam.forward[:] = look
            cam.up[:] = cam_up

    def _add_floor_stripes(self, target: np.ndarray) -> None:
        up, forward = self._up, self._forward
        lateral = 3 - up - forward
        centre = round(target[forward] / STRIPE_SPACING)
        size = np.zeros(3)
        size[forward], size[lateral], size[up] = STRIPE_SPACING / 8, 0.6, 0.001
        for k in range(centre - 12, centre + 13):
            pos = np.zeros(3)
            pos[forward], pos[lateral], pos[up] = k * STRIPE_SPACING, target[lateral], 0.001
            shade = 0.3 if k % 2 else 0.45
            rgba = np.array([shade, shade, shade + 0.05, 1.0], dtype=np.float32)
            if add_geom(self._scene, mujoco.mjtGeom.mjGEOM_BOX, size, pos, rgba) is None:
                return


class VideoRecorder(ClosingObserver):
    """Renders frames of ``env`` (:class:`FrameRenderer`) into an MP4 at ``path``.

    An episode observer (``workers.episode``); or by hand: call :meth:`capture` after
    ``reset`` and after every ``step``; one call in ``every`` makes
    a frame (default: the control rate brought near 30 fps), played at ``control_hz / every``
    frames per second, i.e. in real time. Then :meth:`close` (or use a ``with`` block). The
    file is written from the first frame on: with no frame, none is made. :meth:`render`
    alone returns an image.

    Args:
        path: the .mp4 to write (overwritten; parent directories are created).
        env, width, height, distance, antialias: the frames' (:class:`FrameRenderer`).
        every: control steps per frame.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        env: MuscleEnv,
        width: int = 640,
        height: int = 480,
        every: int | None = None,
        distance: float = 2.5,
        antialias: bool = False,
    ) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._frames = FrameRenderer(env, width, height, distance, antialias)
        self.width, self.height = self._frames.width, self._frames.height
        control_hz = float(env.scene.control_hz)
        self.every = every or max(1, round(control_hz / TARGET_FPS))
        self.fps = control_hz / self.every
        self.frames = 0
        self._calls = 0
        self._closed = False
        self._writer: Any = None  # ffmpeg starts with the first frame

    @property
    def reference(self) -> ReferenceSkeleton:
        """the reference pose's skeleton (scenes with a gait clock)"""
        return self._frames.reference

    # ---- public -----------------------------------------------------------------------------

    def capture(self, env: MuscleEnv) -> None:
        """Render the env's current state if this call is one of every ``every``."""
        if self._closed:
            raise RuntimeError(f"video {self.path} is closed")
        self._calls += 1
        if (self._calls - 1) % self.every:
            return
        frame = self.render(env)
        if self._writer is None:
            self._writer = imageio_ffmpeg.write_frames(
                str(self.path),
                (self.width, self.height),
                fps=self.fps,
                codec="libx264",
                pix_fmt_in="rgb24",
                pix_fmt_out="yuv420p",
                macro_block_size=2,
                ffmpeg_log_level="error",
            )
            self._writer.send(None)
        self._writer.send(frame)
        self.frames += 1

    def render(self, env: MuscleEnv) -> np.ndarray:
        """[height, width, 3] uint8 RGB image of the env's current state."""
        return self._frames.render(env)

    def on_reset(self, env: MuscleEnv, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Episode observer (``workers.episode``): :meth:`capture` the reset pose."""
        self.capture(env)

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
        """Episode observer: :meth:`capture` the step."""
        self.capture(env)

    def close(self) -> None:
        """Finish the MP4 and free the GL resources; idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._writer is not None:
            self._writer.close()
        self._frames.close()
        logger.info("video: %d frames at %.1f fps to %s", self.frames, self.fps, self.path)


def record_video(
    env: MuscleEnv,
    act_fn: Act,
    path: str | os.PathLike[str],
    seed: int,
    max_steps: int | None = None,
    width: int = 640,
    height: int = 480,
    every: int | None = None,
    antialias: bool = False,
) -> dict[str, Any]:
    """One episode of ``act_fn`` (observation [n_obs] -> excitations [n_muscles] in [0, 1])
    on ``env`` from ``env.reset(seed=seed)`` (``workers.episode.run_episode``) until it ends
    or ``max_steps``, rendered to ``path``.

    Returns ``path``, ``frames``, ``fps``, ``steps``, ``return``, ``distance`` (m),
    ``health`` (cause of the last step).
    """
    with VideoRecorder(path, env, width, height, every, antialias=antialias) as video:
        summary = run_episode(env, act_fn, seed, [video], max_steps)
    return {
        "path": str(path),
        "frames": video.frames,
        "fps": video.fps,
        "steps": summary.steps,
        "return": summary.return_,
        "distance": summary.distance_m,
        "health": summary.health,
    }
