"""MuJoCo backend: a scene compiled to a pruned ``MjModel`` (``compile``), stepped
with health checks.

MuJoCo does not raise on numerical failure: on a NaN or huge acceleration it resets the
state (``mj_resetData``) and only bumps ``data.warning`` counters. So every control step
zeroes the counters, steps, and then reads them (BADQACC, BADQPOS, BADQVEL, CNSTRFULL,
CONTACTFULL) besides checking the state for non-finite values.
"""

from __future__ import annotations

import logging

import mujoco
import numpy as np
from gaitforge.workers.scenes import Scene
from gaitforge.workers.sim.base import (
    HEALTHY,
    MAX_SPEED,
    BodyPose,
    Health,
    Pose,
    Reflex,
    SimState,
    check_pose_names,
)
from gaitforge.workers.sim.mujoco.compile import OBSTACLE_PREFIX, compile_scene
from gaitforge.workers.sim.mujoco.couplings import set_coupled_qpos
from gaitforge.workers.sim.mujoco.drawing import body_frames, muscle_paths
from gaitforge.workers.sim.mujoco.pose import PoseSetter
from gaitforge.workers.sim.mujoco.warning_log import route_warnings

logger = logging.getLogger(__name__)
route_warnings()  # MuJoCo's warnings to logging, not to MUJOCO_LOG.TXT in the cwd

WATCHED_WARNINGS = {
    "mujoco_badqacc": mujoco.mjtWarning.mjWARN_BADQACC,
    "mujoco_badqpos": mujoco.mjtWarning.mjWARN_BADQPOS,
    "mujoco_badqvel": mujoco.mjtWarning.mjWARN_BADQVEL,
    "mujoco_cnstrfull": mujoco.mjtWarning.mjWARN_CNSTRFULL,
    "mujoco_contactfull": mujoco.mjtWarning.mjWARN_CONTACTFULL,
}
AXES = {"gait2d": (1, 0), "myoleg": (2, 0), "myoelbow": (2, 0)}
"""(up, forward) world axes per body; neutral bodies are Y-up, X-forward."""
PELVIS_UP, PELVIS_FORWARD = 1, 0
"""The pelvis frame's up and forward axes (Y and X in OpenSim-derived bodies, MyoLeg's
included)."""
STAND_KEY = "stand"
"""Keyframe that, where a model has it, is the reset pose (MyoLeg)."""


class MujocoSimulator:
    """A scene on MuJoCo. Picklable: it pickles as its scene plus its integration state."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.model, self.report, topology = compile_scene(scene)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.up_axis, self.forward_axis = AXES.get(scene.body, (1, 0))
        self.dof_names = list(self.report.plan.kept_dofs)
        jids = np.array([self._joint_id(n) for n in self.dof_names], dtype=int)
        self._qadr = m.jnt_qposadr[jids]
        self._vadr = m.jnt_dofadr[jids]
        limited = m.jnt_limited[jids].astype(bool)
        self._qlo = np.where(limited, m.jnt_range[jids, 0], -np.inf)
        self._qhi = np.where(limited, m.jnt_range[jids, 1], np.inf)
        self.muscle_names = [m.actuator(i).name for i in range(m.nu)]
        self.foot_names = sorted(topology.feet)
        self._geom_foot = np.full(m.ngeom, -1, dtype=int)
        for k, foot in enumerate(self.foot_names):
            for geom in topology.feet[foot]:
                gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, geom)
                if gid >= 0:
                    self._geom_foot[gid] = k
        self._pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        self._obstacle_ids = np.array(
            [
                mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{OBSTACLE_PREFIX}{i}")
                for i in range(self.report.plan.obstacles)
            ],
            dtype=int,
        )
        if len(self._obstacle_ids):
            # The obstacles are world geoms moved every reset, but the world body's bounding
            # volume tree is built once, at compile time, around their parked places: with
            # it the midphase dropped every foot pair of the six farthest spheres (their
            # branch lay 100 m behind) and the feet went through them. Without
            # it each geom pair of two bodies is tested by its bounding spheres
            # (geom_rbound, set with each placement).
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
        initial = {
            **topology.root_defaults,
            **{d: topology.dof_defaults[d] for d in self.dof_names},
        }
        self._init_adr = np.array([m.jnt_qposadr[self._joint_id(n)] for n in initial], dtype=int)
        self._init_val = np.array(list(initial.values()))
        self._foot_spheres = np.array(
            [
                g
                for g in range(m.ngeom)
                if self._geom_foot[g] >= 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
            ],
            dtype=int,
        )
        self._lift_adr = self._root_slide_along(self.up_axis)
        self._stand_key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, STAND_KEY)
        # muscles found by their activation dynamics
        self._muscle_act = m.actuator_actadr[
            (m.actuator_dyntype == mujoco.mjtDyn.mjDYN_MUSCLE) & (m.actuator_actadr >= 0)
        ]
        self._rng = np.random.default_rng(0)
        self._contact_timeconst = float("nan")
        self._set_contact_timeconst(self._rng)
        self._locked = set(self.report.plan.locked_dofs)
        self._foot_geoms = [
            np.flatnonzero(self._geom_foot == k) for k in range(len(self.foot_names))
        ]
        self._poser = PoseSetter(
            m,
            self.dof_names,
            (self._qadr, self._qlo, self._qhi),
            self._pelvis,
            (self.up_axis, self.forward_axis),
        )

    # ---- protocol -------------------------------------------------------------------

    def reset(self, seed: int) -> None:
        m, d = self.model, self.data
        self._rng = np.random.default_rng(seed)
        self._set_contact_timeconst(self._rng)
        if self._stand_key >= 0:
            mujoco.mj_resetDataKeyframe(m, d, self._stand_key)
        else:
            mujoco.mj_resetData(m, d)
            d.qpos[self._init_adr] = self._init_val
        noise = self.scene.init_noise
        jitter = self._rng.uniform(-noise, noise, len(self._qadr))
        d.qpos[self._qadr] = np.clip(d.qpos[self._qadr] + jitter, self._qlo, self._qhi)
        set_coupled_qpos(m, d)  # an imported body's coupled dofs follow their drivers
        self._place_obstacles()
        self._touch_floor()
        floor = self.scene.mujoco.muscle_min_activation
        if floor > 0:  # the muscles start at their least activation, as OpenSim's do
            d.act[self._muscle_act] = np.maximum(d.act[self._muscle_act], floor)
        mujoco.mj_forward(m, d)

    def step(self, excitations: np.ndarray, duration: float) -> Health:
        m, d = self.model, self.data
        t0 = self._start_step()
        d.ctrl[:] = np.clip(np.where(np.isnan(excitations), 0.0, excitations), 0.0, 1.0)
        mujoco.mj_step(m, d, nstep=max(1, round(duration / m.opt.timestep)))
        return self._health(t0)

    def step_reflex(
        self, reflex: Reflex, duration: float, updates: int
    ) -> tuple[np.ndarray, Health]:
        m, d = self.model, self.data
        t0 = self._start_step()
        substeps = max(1, round(duration / m.opt.timestep / updates))
        total = np.zeros(m.nu)
        done = 0
        qpos, qvel = d.qpos, d.qvel
        for done in range(1, updates + 1):  # noqa: B007 (the count is read after the loop)
            excitation = reflex(qpos[self._qadr], qvel[self._vadr])  # finite while the state is
            total += excitation
            d.ctrl[:] = excitation
            mujoco.mj_step(m, d, nstep=substeps)
            if not np.isfinite(qvel).all():
                break
        return total / done, self._health(t0)

    def _start_step(self) -> float:
        for warning in WATCHED_WARNINGS.values():
            self.data.warning[warning].number = 0
        return float(self.data.time)

    def _health(self, t0: float) -> Health:
        """The health of the step that began at simulated time ``t0``."""
        d = self.data
        for cause, warning in WATCHED_WARNINGS.items():
            if d.warning[warning].number > 0:
                return Health(cause)
        if d.time < t0:
            return Health("mujoco_reset")
        if not (
            np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all() and np.isfinite(d.act).all()
        ):
            return Health("nan_state")
        if np.abs(d.qvel).max(initial=0.0) > MAX_SPEED:
            return Health("diverged_speed")
        return Health(HEALTHY)

    def state(self) -> SimState:
        m, d = self.model, self.data
        if self._pelvis >= 0:
            vel = np.zeros(6)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._pelvis, vel, 0)
            pelvis_pos = d.xpos[self._pelvis].copy()
            frame = d.xmat[self._pelvis].reshape(3, 3)
            pelvis_up, pelvis_forward = frame[:, PELVIS_UP].copy(), frame[:, PELVIS_FORWARD].copy()
            angvel, linvel = vel[:3].copy(), vel[3:].copy()
        else:
            pelvis_pos, angvel, linvel = np.zeros(3), np.zeros(3), np.zeros(3)
            pelvis_up, pelvis_forward = np.eye(3)[self.up_axis], np.eye(3)[self.forward_axis]
        return SimState(
            time=float(d.time),
            dof_pos=d.qpos[self._qadr].copy(),
            dof_vel=d.qvel[self._vadr].copy(),
            pelvis_pos=pelvis_pos,
            pelvis_up=pelvis_up,
            pelvis_forward=pelvis_forward,
            pelvis_vel=linvel,
            pelvis_angvel=angvel,
            activations=d.act.copy() if m.na else np.zeros(m.nu),
            foot_forces=self._foot_forces(),
        )

    def moment_arms(self) -> np.ndarray:
        m, d = self.model, self.data
        # at the present pose (after mj_step, actuator_moment is the pre-step pose's)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        mujoco.mj_transmission(m, d)
        dense = np.zeros((m.nu, m.nv))
        mujoco.mju_sparse2dense(
            dense, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind
        )
        # MuJoCo's muscle force is negative in tension: torque = moment * force
        return -dense[:, self._vadr]

    def muscle_sensors(self) -> tuple[np.ndarray, np.ndarray]:
        """See ``Simulator.muscle_sensors``. MuJoCo's muscle maps its actuator length onto a
        normalised fibre length through ``lengthrange`` and ``range`` (``gainprm[:2]``; see
        ``workers.sim.mujoco.build``); its peak force is ``gainprm[2]`` and its force is
        negative in tension. At the present pose and speeds (``mj_forward``: after
        ``mj_step`` the actuator lengths and forces are the step's start's)."""
        m, d = self.model, self.data
        mujoco.mj_forward(m, d)
        lo, hi = m.actuator_lengthrange[:, 0], m.actuator_lengthrange[:, 1]
        r0, r1 = m.actuator_gainprm[:, 0], m.actuator_gainprm[:, 1]
        optimal = (hi - lo) / (r1 - r0)
        length = r0 + (d.actuator_length - lo) / optimal
        return length, -d.actuator_force / m.actuator_gainprm[:, 2]

    def set_pose(self, pose: Pose) -> None:
        """See ``Simulator.set_pose`` and ``workers.sim.mujoco.pose``."""
        check_pose_names(pose, self.scene.body, self.dof_names, self._locked)
        self._poser.apply(self.data, pose)

    def push(self, force: np.ndarray) -> None:
        if self.scene.pushes is None:
            raise ValueError(f"scene {self.scene.name!r} has no pushes")
        self.data.xfrc_applied[self._pelvis, :3] = force  # at the body's centre of mass

    def foot_positions(self) -> dict[str, np.ndarray]:
        d = self.data
        return {
            foot: d.geom_xpos[ids].mean(axis=0) if len(ids) else np.full(3, np.nan)
            for foot, ids in zip(self.foot_names, self._foot_geoms, strict=True)
        }

    def obstacles(self) -> np.ndarray:
        m = self.model
        if not len(self._obstacle_ids):
            return np.zeros((0, 3))
        pos = m.geom_pos[self._obstacle_ids]
        return np.column_stack(
            [pos[:, self.forward_axis], pos[:, self.up_axis], m.geom_size[self._obstacle_ids, 0]]
        )

    def get_state(self) -> dict[str, np.ndarray]:
        m, d = self.model, self.data
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        physics = np.empty(mujoco.mj_stateSize(m, spec))
        mujoco.mj_getState(m, d, physics, spec)
        return {
            "physics": physics,
            "obstacle_pos": m.geom_pos[self._obstacle_ids].copy(),
            "obstacle_radius": m.geom_size[self._obstacle_ids, 0].copy(),
            "contact_timeconst": np.array([self._contact_timeconst]),
        }

    def set_state(self, state: dict[str, np.ndarray]) -> None:
        m, d = self.model, self.data
        self._set_obstacles(state["obstacle_pos"], state["obstacle_radius"])
        self._apply_contact_timeconst(float(state["contact_timeconst"][0]))
        mujoco.mj_setState(m, d, state["physics"], mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(m, d)

    def poison(self) -> None:
        self.data.qvel[:] = np.nan

    # ---- read-outs for drawing (``workers.sim.mujoco.drawing``: positions as of the last
    # kinematics pass, lagging the state by one timestep at most)

    def body_frames(self) -> dict[str, BodyPose]:
        return body_frames(self.model, self.data)

    def muscle_paths(self) -> dict[str, np.ndarray]:
        """Tendon path points (sites and wrap tangent points; pulley markers dropped)."""
        return muscle_paths(self.model, self.data, self.muscle_names)

    def contact_spheres(self) -> dict[str, np.ndarray]:
        m, d = self.model, self.data
        spheres: dict[str, list] = {foot: [] for foot in self.foot_names}
        for g in self._foot_spheres:
            spheres[self.foot_names[self._geom_foot[g]]].append(
                [*d.geom_xpos[g], m.geom_size[g, 0]]
            )
        return {foot: np.array(s, dtype=float).reshape(-1, 4) for foot, s in spheres.items()}

    def coordinates(self) -> dict[str, float]:
        m, d = self.model, self.data
        scalar = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)}
        return {
            m.joint(j).name: float(d.qpos[m.jnt_qposadr[j]])
            for j in range(m.njnt)
            if int(m.jnt_type[j]) in scalar
        }

    # ---- pickling: rebuild the model from the scene, then restore the state ----------

    def __getstate__(self) -> dict:
        return {"scene": self.scene, "state": self.get_state()}

    def __setstate__(self, saved: dict) -> None:
        self.__init__(saved["scene"])  # type: ignore[misc]
        self.set_state(saved["state"])

    # ---- helpers ----------------------------------------------------------------------

    def _joint_id(self, name: str) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, name)

    def _root_slide_along(self, axis: int) -> int:
        """qpos address of a root slide dof along world ``axis`` (-1 if there is none)."""
        m = self.model
        for j in range(m.njnt):
            if (
                m.jnt_bodyid[j] == self._pelvis
                and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
                and abs(m.jnt_axis[j][axis]) > 0.999
            ):
                return int(m.jnt_qposadr[j])
        return -1

    def _set_contact_timeconst(self, rng: np.random.Generator) -> None:
        """The contacts' time constant (s) from ``scene.mujoco.contact_timeconst_s``: the
        value, or one drawn from the range with ``rng``; nothing if it is None (MuJoCo's)."""
        timeconst = self.scene.mujoco.contact_timeconst_s
        if timeconst is not None:
            drawn = rng.uniform(*timeconst) if isinstance(timeconst, tuple) else timeconst
            self._apply_contact_timeconst(float(drawn))

    def _apply_contact_timeconst(self, timeconst: float) -> None:
        """Every geom's and explicit pair's ``solref`` time constant (a contact mixes its two
        geoms' ``solref``, so all alike make it ``timeconst``); nan: leave them."""
        if np.isfinite(timeconst):
            self.model.geom_solref[:, 0] = timeconst
            self.model.pair_solref[:, 0] = timeconst
            self._contact_timeconst = timeconst

    def _touch_floor(self) -> None:
        """Raise or lower the body so its lowest contact sphere just touches the floor."""
        if self._lift_adr < 0 or not len(self._foot_spheres):
            return
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        ids = self._foot_spheres
        lowest = np.min(d.geom_xpos[ids, self.up_axis] - m.geom_size[ids, 0])
        d.qpos[self._lift_adr] -= lowest

    def _place_obstacles(self) -> None:
        spec = self.scene.obstacles
        if spec is None or not len(self._obstacle_ids):
            return
        ahead, height, radius = spec.draw(self._rng).T
        pos = np.zeros((len(radius), 3))
        pos[:, self.forward_axis] = ahead
        pos[:, self.up_axis] = height
        self._set_obstacles(pos, radius)

    def _set_obstacles(self, pos: np.ndarray, radius: np.ndarray) -> None:
        """Move and resize obstacle spheres, bounding volumes included (for the broadphase)."""
        m, ids = self.model, self._obstacle_ids
        m.geom_pos[ids] = pos
        m.geom_size[ids, 0] = radius
        m.geom_rbound[ids] = radius
        m.geom_aabb[ids, 3:] = radius[:, None]

    def _foot_forces(self) -> np.ndarray:
        m, d = self.model, self.data
        forces = np.zeros(len(self.foot_names))
        wrench = np.zeros(6)
        for i in range(d.ncon):
            contact = d.contact[i]
            foot = max(self._geom_foot[contact.geom1], self._geom_foot[contact.geom2])
            if foot >= 0:
                mujoco.mj_contactForce(m, d, i, wrench)
                forces[foot] += abs(wrench[0])
        return forces
