"""Gymnasium environment over one scene on one simulator backend.

Observation (float32, names in ``env.obs_names``): the parts of
``workers.scenes.io_names.OBSERVATION`` the scene observes, in that table's order (their
names, sizes and units there), each read by its reader in :data:`OBSERVATION_READERS`. The
target speed is the scene's or the episode's draw with ``task.target_speed_range`` (0
without one), the reach target the episode's draw from ``task.reach_range`` (else 0); the
observed spheres are the scene's ``obstacles.observe_ahead`` nearest ahead of the pelvis
(one whose far edge it has not passed), nearest first, with 0, 0, 0 for each that does not
exist; ``phase_mirror`` is +1 in a mirrored episode of the gait clock (``task.clock``), -1
otherwise.
Action (``env.act_names``): excitations [n_muscles] in [0, 1]; or, with ``action.kind:
joint_targets``, targets [n_dofs] in [0, 1] around a base pose that the reflex layer
(``workers.reflex``) turns into excitations (``prev_exc`` then holds the step's mean
excitations, and the effort terms use them); or, with ``reflex_gait``, a residual [n_muscles]
added to the reflex gait controller's excitations (``workers.gait_reflex``; 0.5 adds nothing).

Every step's info holds ``distance`` (m the pelvis went forward since the reset), ``turned``
(rad the pelvis turned about the vertical since the reset, counter-clockwise seen from above;
exactly 0 on a planar body), ``sim_time`` (s) and ``step``. Scenes with the gait clock
(``workers.gait_clock``) report ``info["clock"] = {"phase", "mirrored"}`` on reset and every
step; ``reference_state()`` is the clock's reference state now. Imitation scenes
(``workers.imitation``) also start episodes in the motion, add the tracking terms to the
reward, end the episode when the pose error passes the scene's bound, and report
``info["imitation"] = {"phase", "pose_error_rad", "kept", "mirrored"}``.

On scenes with obstacles ``touching_obstacle()`` says whether a foot touches one now (the
evaluation asks after every step, so that it can tell the falls that came after a touch
from the others; a touch shorter than a control step may fall between two steps' ends).

A simulator failure never raises and never reaches the observation: the step is
``terminated`` with ``info["health"]`` naming the cause, reward 0, and the last healthy
observation repeated.
"""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np
from gaitforge.workers.bodies.reflex_wiring import load_wiring
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.gait_clock import GaitClock
from gaitforge.workers.gait_reflex import GaitReflex
from gaitforge.workers.imitation import Imitation
from gaitforge.workers.motions import MotionState
from gaitforge.workers.reflex import ReflexLayer
from gaitforge.workers.rewards import StepContext, reward_terms, term_names, weighted
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.io_names import OBSERVATION, action_layout, observation_parts
from gaitforge.workers.scenes.reflex_parameters import parameter_vector
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.base import HEALTHY, Health, SimState
from gaitforge.workers.sim.pose import cross3, pelvis_frame, turn_about_up

GRAVITY = 9.81

ObservationReader = Callable[["MuscleEnv", SimState], "np.ndarray | list[float]"]
"""Reads one part of the observation from the env and its state: as many values as the
part's entry names (``workers.scenes.io_names.OBSERVATION``)."""


class MuscleEnv(gym.Env[np.ndarray, np.ndarray]):
    """One scene (by catalogue name, path or spec) on ``backend``."""

    metadata = {"render_modes": []}  # noqa: RUF012 (gymnasium's convention)

    def __init__(self, scene: str | Scene, backend: str = "mujoco") -> None:
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        if backend not in self.scene.backends:
            raise ValueError(
                f"backend {backend!r}: scene {self.scene.name!r} runs on {self.scene.backends}"
            )
        self.backend = backend
        self.sim = make_simulator(self.scene, backend)
        self.dt = 1.0 / self.scene.control_hz
        task = self.scene.task
        self._reach_index = (
            self.sim.dof_names.index(task.reach_dof) if task.reach_dof is not None else None
        )
        self._reach_target = 0.0
        self._target_speed = task.target_speed
        """m/s this episode: the scene's, or drawn from its ``target_speed_range``"""
        self._weight = GRAVITY * self.sim.report.mass
        self.reward_term_names = term_names(task)
        self.clock = GaitClock(self.scene, self.dt) if task.clock else None
        self.imitation = (
            Imitation(self.scene, self.sim, self.clock)
            if task.imitate is not None and self.clock is not None
            else None
        )
        self._imitation_info: dict = {}
        parts = observation_parts(
            self.scene, self.sim.dof_names, self.sim.foot_names, self.sim.muscle_names
        )
        self.obs_names = [name for _, names in parts for name in names]
        self._obs_parts = tuple((key, len(names)) for key, names in parts)
        """(key, size) of each part of the observation, in order"""
        n_mus = len(self.sim.muscle_names)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, (len(self.obs_names),), dtype=np.float32
        )
        targets = self.scene.action.targets
        self.reflex = ReflexLayer(self.scene.action, self.sim) if targets else None
        self.gait = self._gait_controller() if self.scene.action.gait else None
        self.act_names = action_layout(self.scene, self.sim.dof_names, self.sim.muscle_names)
        self.action_space = gym.spaces.Box(0.0, 1.0, (len(self.act_names),), dtype=np.float32)
        defaults = topology_for(self.scene.body).dof_defaults
        self._default_pose = np.array([defaults.get(d, 0.0) for d in self.sim.dof_names])
        self._prev_excitation = np.zeros(n_mus)
        self._state: SimState | None = None
        self._obs = np.zeros(len(self.obs_names), dtype=np.float32)
        self._steps = 0
        self._start_forward = 0.0
        self._start_frame = np.eye(3)
        self._pushes = np.zeros((0, 4))
        """this episode's pushes (``Pushes.draw``: start s, end s, direction rad, N)"""

    # ---- gymnasium API ----------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.sim.reset(int(self.np_random.integers(2**31 - 1)))
        if self.scene.task.reach_range is not None:
            self._reach_target = float(self.np_random.uniform(*self.scene.task.reach_range))
        if self.scene.task.target_speed_range is not None:
            self._target_speed = float(self.np_random.uniform(*self.scene.task.target_speed_range))
            if self.clock is not None:
                self.clock.follow_target_speed(self._target_speed)
        self._prev_excitation = np.zeros(len(self.sim.muscle_names))
        self._steps = 0
        info: dict = {"health": HEALTHY}
        if self.imitation is not None:
            pose = self.imitation.start(self.np_random)
            if pose is not None:  # else the reset's standing pose
                self.sim.set_pose(pose)
        elif self.clock is not None:
            self.clock.start(self.np_random)
        if self.gait is not None:
            start = self.gait.start_pose(
                self.np_random, self.scene.init_noise, self.scene.action.start_speed
            )
            self.sim.set_pose(start)
            self.gait.reset(self.sim.state())
        self._state = self.sim.state()
        if self.clock is not None:
            info["clock"] = self._clock_info()
        if self.imitation is not None:
            assert self.clock is not None
            ref = self.clock.reference(0)
            error = self.imitation.pose_error(self._state, ref, self.clock.ramp(0))
            info["imitation"] = self._imitation_info = {
                **info["clock"],
                "pose_error_rad": float(np.sqrt(np.mean(error**2))),
                "kept": True,
            }
        self._start_forward = float(self._state.pelvis_pos[self.sim.forward_axis])
        self._start_frame = pelvis_frame(self._state.pelvis_up, self._state.pelvis_forward)
        if self.scene.pushes is not None:
            self._pushes = self.scene.pushes.draw(self.np_random, self.scene.episode_s)
        self._obs = self._observe(self._state, check=True)
        return self._obs.copy(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        if self.scene.pushes is not None:
            self.sim.push(self.push_force(self._steps * self.dt))
        self._steps += 1
        truncated = self._steps >= self.scene.steps_per_episode
        if self.reflex is not None:
            excitation, health = self._step_reflex(action)
        else:
            excitation = np.asarray(action, dtype=np.float64)
            excitation = np.where(np.isnan(excitation), 0.0, excitation)  # infinities: clipped
            if self.gait is not None:
                residual = (2.0 * np.clip(excitation, 0.0, 1.0) - 1.0) * self.scene.action.residual
                excitation = self.gait(self._state) + residual
            excitation = np.clip(excitation, 0.0, 1.0)
            health = self.sim.step(excitation, self.dt)
        state = self.sim.state() if health.ok else None
        if state is not None and not state.is_finite():
            health, state = Health("nan_state"), None
        if state is None:
            info = {
                "health": health.cause,
                "reward_terms": dict.fromkeys(self.reward_term_names, 0.0),
            }
            info.update(self._episode_info(self._state))
            if self.clock is not None:
                info["clock"] = self._clock_info()
            if self.imitation is not None:
                info["imitation"] = {**self._imitation_info, "kept": False}
            return self._obs.copy(), 0.0, True, truncated, info
        ctx = StepContext(
            previous=self._state,
            excitation=excitation,
            previous_excitation=self._prev_excitation,
            dt=self.dt,
            forward_axis=self.sim.forward_axis,
            up_axis=self.sim.up_axis,
            target_speed=self.target_speed(),
            reach_index=self._reach_index,
            reach_target=self._reach_target,
        )
        terms = weighted(reward_terms(state, ctx), self.scene.task.reward)
        clock_info = self._clock_info() if self.clock is not None else None
        kept = True
        if self.imitation is not None:
            assert clock_info is not None
            tracking = self.imitation.track(state, self._state, self.sim, self._steps)
            terms.update(self.imitation.weighted(tracking.kernels))
            kept = self._imitation_info["kept"] and self.imitation.kept(tracking.pose_error_rad)
            self._imitation_info = {
                **clock_info,
                "pose_error_rad": tracking.pose_error_rad,
                "kept": kept,
            }
        self._prev_excitation = excitation
        self._state = state
        self._obs = self._observe(state)
        fell = self._fell(state)
        info = {"health": HEALTHY, "reward_terms": terms, "fell": fell}
        info.update(self._episode_info(state))
        ended = fell
        if clock_info is not None:
            info["clock"] = clock_info
        if self.imitation is not None:
            info["imitation"] = dict(self._imitation_info)
            info["lost_track"] = not kept
            ended = fell or not kept
        return self._obs.copy(), float(sum(terms.values())), ended, truncated and not ended, info

    def _gait_controller(self) -> GaitReflex:
        """The scene's reflex gait controller (``action.kind: reflex_gait``).

        Raises:
            SpecError: the wiring is another body's.
            ValueError: the wiring names what the scene does not keep.
        """
        action = self.scene.action
        wiring = load_wiring(self.scene.body, action.wiring)
        parameters = parameter_vector(action.parameters)
        return GaitReflex(wiring, self.sim, self.scene.control_hz, parameters)

    def _step_reflex(self, action: np.ndarray) -> tuple[np.ndarray, Health]:
        """One control step through the reflex layer: the targets' base is the motion's pose
        at the step's end (with the gait clock; blended from the default pose while a standing
        start ramps into the motion) or the default pose; returns the step's mean excitations
        [n_muscles] and its health."""
        assert self.reflex is not None
        base, speeds = self._default_pose, np.zeros_like(self._default_pose)
        if self.clock is not None:
            base, speeds = self.clock.target_base(self._steps, self.sim.dof_names, base)
        self.reflex.set_targets(action, base, speeds)
        return self.sim.step_reflex(self.reflex, self.dt, self.scene.reflex_chunks)

    def push_force(self, time: float) -> np.ndarray:
        """[3] N in the world: the push held over the control step starting at ``time`` s
        (zeros between pushes)."""
        for start, end, angle, magnitude in self._pushes:
            if start <= time < end:
                forward, up = np.eye(3)[self.sim.forward_axis], np.eye(3)[self.sim.up_axis]
                right = cross3(forward, up)
                return magnitude * (np.cos(angle) * forward + np.sin(angle) * right)
        return np.zeros(3)

    @property
    def excitation(self) -> np.ndarray:
        """[n_muscles] in [0, 1]: the excitations of the last step (zeros after a reset)."""
        return self._prev_excitation

    def target_speed(self) -> float | None:
        """The target_speed term's target (m/s) for the step just taken (the scene's, or with
        ``speed_target_from_clock`` the gait clock's; None without one)."""
        target = self._target_speed
        if self.clock is None:
            return target
        return self.clock.target_speed(self._steps, target)

    def reference_state(self) -> MotionState | None:
        """The clock's reference state now (mirrored if this episode is), for drawing; None
        if the scene has no gait clock."""
        return self.clock.reference(self._steps) if self.clock is not None else None

    def _clock_info(self) -> dict:
        """``info["clock"]`` now: the phase [0, 1) and whether the episode is mirrored."""
        assert self.clock is not None
        return {"phase": self.clock.phase(self._steps), "mirrored": self.clock.mirrored}

    # ---- observation --------------------------------------------------------------------

    def _observe(self, s: SimState, check: bool = False) -> np.ndarray:
        """The observation [n_obs] (float32) in state ``s``: each part the scene observes,
        read by its reader, in ``OBSERVATION``'s order.

        Raises:
            RuntimeError: with ``check`` (on reset), a part's reader read another count of
                values than the part has names.
        """
        parts = [np.ravel(OBSERVATION_READERS[key](self, s)) for key, _ in self._obs_parts]
        if check:
            for (key, size), part in zip(self._obs_parts, parts, strict=True):
                if part.size != size:
                    raise RuntimeError(
                        f"scene {self.scene.name!r} on {self.backend}: observation part "
                        f"{key!r} read {part.size} values for its {size} names"
                    )
        return np.concatenate(parts).astype(np.float32)

    def _observed_obstacles(self, s: SimState) -> np.ndarray:
        """[3 * observe_ahead]: see the module's docstring."""
        spec = self.scene.obstacles
        here = s.pelvis_pos[self.sim.forward_axis]
        obstacles = self.sim.obstacles()
        obstacles = obstacles[np.argsort(obstacles[:, 0])]
        is_ahead = obstacles[:, 0] + obstacles[:, 2] > here
        relative = obstacles - [here, 0.0, 0.0]
        ahead = relative[is_ahead][: spec.observe_ahead]
        seen = np.zeros((spec.observe_ahead, 3))
        seen[: len(ahead)] = ahead
        return seen

    def touching_obstacle(self) -> bool | None:
        """Whether a foot's contact sphere overlaps an obstacle sphere now, as both
        simulators' contacts begin (the feet's spheres are what meets the obstacles on
        either); None if the scene has no obstacles. For observers (about 0.1 ms; the step
        itself does not ask)."""
        if self.scene.obstacles is None:
            return None
        obstacles = self.sim.obstacles()
        if not len(obstacles):
            return False
        feet = np.concatenate(list(self.sim.contact_spheres().values()))
        forward = feet[:, None, self.sim.forward_axis] - obstacles[None, :, 0]
        up = feet[:, None, self.sim.up_axis] - obstacles[None, :, 1]
        across = np.delete(feet[:, :3], [self.sim.forward_axis, self.sim.up_axis], axis=1)
        reach = feet[:, None, 3] + obstacles[None, :, 2]
        return bool((forward**2 + up**2 + across**2 < reach**2).any())

    # ---- episode bookkeeping ------------------------------------------------------------

    def _fell(self, s: SimState) -> bool:
        limit = self.scene.task.min_pelvis_height
        return limit is not None and float(s.pelvis_pos[self.sim.up_axis]) < limit

    def _distance(self, s: SimState) -> float:
        """m the pelvis has gone forward since the reset."""
        return float(s.pelvis_pos[self.sim.forward_axis]) - self._start_forward

    def _turned(self, s: SimState) -> float:
        """rad the pelvis has turned about the vertical since the reset (counter-clockwise
        seen from above; 0 for a planar body)."""
        frame = pelvis_frame(s.pelvis_up, s.pelvis_forward)
        return turn_about_up(self._start_frame, frame, self.sim.up_axis)

    def _episode_info(self, s: SimState) -> dict:
        return {
            "distance": self._distance(s),
            "turned": self._turned(s),
            "sim_time": s.time,
            "step": self._steps,
        }


def _gait_phase(env: MuscleEnv, s: SimState) -> list[float]:
    assert env.clock is not None
    return env.clock.observe(env._steps)


OBSERVATION_READERS: dict[str, ObservationReader] = {
    "dof_pos": lambda env, s: s.dof_pos,
    "dof_vel": lambda env, s: s.dof_vel,
    "pelvis_height": lambda env, s: [s.pelvis_pos[env.sim.up_axis]],
    "pelvis_up": lambda env, s: s.pelvis_up,
    "pelvis_vel": lambda env, s: s.pelvis_vel,
    "pelvis_angvel": lambda env, s: s.pelvis_angvel,
    "foot_forces": lambda env, s: s.foot_forces / env._weight,
    "activations": lambda env, s: s.activations,
    "prev_excitation": lambda env, s: env._prev_excitation,
    "target_speed": lambda env, s: [env._target_speed or 0.0],
    "reach_target": lambda env, s: [env._reach_target],
    "obstacles": lambda env, s: env._observed_obstacles(s),
    "gait_phase": _gait_phase,
}
"""The reader of each part of ``workers.scenes.io_names.OBSERVATION``, by its key (the
order is the table's; every key has one reader, checked on import)."""

if set(OBSERVATION_READERS) != {entry.key for entry in OBSERVATION}:
    raise RuntimeError(
        "workers.env: the observation's readers "
        f"{sorted(OBSERVATION_READERS)} are not one per part of "
        f"workers.scenes.io_names.OBSERVATION {[entry.key for entry in OBSERVATION]}"
    )
