"""Gymnasium environment over one scene on one simulator backend.

Observation (float32, names in ``env.obs_names``), in this order:
    dof angles [n_dofs] (rad or m) and speeds [n_dofs];
    locomotion only: pelvis height (m), pelvis up axis in world [3], pelvis linear [3] (m/s)
    and angular [3] (rad/s) velocity, normal ground force per foot [n_feet] (body weights);
    muscle activations [n_muscles]; previous excitations [n_muscles];
    task: target speed (m/s; the episode's draw with ``task.target_speed_range``) or reach
    target (rad); with obstacles, the scene's ``obstacles.observe_ahead`` nearest spheres
    ahead of the pelvis (one whose far edge it has not passed): forward distance from the
    pelvis, centre height, radius (m; 0, 0, 0 for each that does not exist); with the gait
    clock (``task.clock``): its phase as ``phase_sin``, ``phase_cos``, and ``phase_mirror``
    (+1 in a mirrored episode, -1 otherwise).
Action (``env.act_names``): excitations [n_muscles] in [0, 1]; or, with ``action.kind:
joint_targets``, targets [n_dofs] in [0, 1] around a base pose that the reflex layer
(``workers.reflex``) turns into excitations (``prev_exc`` then holds the step's mean
excitations, and the effort terms use them).

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

import gymnasium as gym
import numpy as np
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.gait_clock import GaitClock
from gaitforge.workers.imitation import Imitation
from gaitforge.workers.motions import MotionState
from gaitforge.workers.reflex import ReflexLayer
from gaitforge.workers.rewards import StepContext, reward_terms, term_names, weighted
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.io_names import action_layout, observation_layout
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.base import HEALTHY, Health, SimState
from gaitforge.workers.sim.pose import pelvis_frame, turn_about_up

GRAVITY = 9.81


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
        self._locomotion = task.kind == "locomotion"
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
        self.obs_names = self._observation_names()
        n_mus = len(self.sim.muscle_names)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, (len(self.obs_names),), dtype=np.float32
        )
        targets = self.scene.action.targets
        self.reflex = ReflexLayer(self.scene.action, self.sim) if targets else None
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
        self._obs = self._observe(self._state)
        return self._obs.copy(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        self._steps += 1
        truncated = self._steps >= self.scene.steps_per_episode
        if self.reflex is None:
            excitation = np.clip(np.nan_to_num(np.asarray(action, dtype=np.float64)), 0.0, 1.0)
            health = self.sim.step(excitation, self.dt)
        else:
            excitation, health = self._step_reflex(action)
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

    def _observation_names(self) -> list[str]:
        sim = self.sim
        return observation_layout(self.scene, sim.dof_names, sim.foot_names, sim.muscle_names)

    def _observe(self, s: SimState) -> np.ndarray:
        parts = [s.dof_pos, s.dof_vel]
        if self._locomotion:
            parts += [
                [s.pelvis_pos[self.sim.up_axis]],
                s.pelvis_up,
                s.pelvis_vel,
                s.pelvis_angvel,
                s.foot_forces / self._weight,
            ]
        parts += [s.activations, self._prev_excitation]
        parts.append([self._target_speed or 0.0] if self._locomotion else [self._reach_target])
        if self.scene.obstacles is not None:
            parts.append(self._observed_obstacles(s))
        if self.clock is not None:
            parts.append(self.clock.observe(self._steps))
        return np.concatenate([np.ravel(p) for p in parts]).astype(np.float32)

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
