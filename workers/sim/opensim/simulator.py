"""OpenSim backend: a scene built as an ``opensim.Model`` and integrated with ``Manager``.

A control step sets the excitation controller's constants and integrates one control period
with a new ``Manager`` (``Manager.initialize`` cannot be called twice) started from the
current state under the scene's fidelity profile. A Manager per step rather than per
episode makes a step depend on the state alone, not on the integrator's step-size history,
so a pickled env continues bit for bit. The reflex layer's updates within one control step
share that step's Manager (the first update makes it): each sets the constants and
integrates on to its end time, and its excitations act from its start. At a fixed step this
is the same state bit for bit as a new Manager per update; with error control it is as close
to a converged reference, the difference between the two scaling with the accuracy asked;
and it saves ``Manager.initialize`` each update (measured by ``bench/opensim_reflex_manager.py``
at 41d5e6b).

Every SimTK exception ("Integrator step failed", "Unable to advance time", ...), a step
slower than ``scene.opensim.step_wall_limit_s`` and a non-finite state end in a named
:class:`Health`; nothing raises out of ``step``. OpenSim's own log is silenced. The model
is rebuilt every ``scene.opensim.rebuild_every`` episodes, a bound on the memory OpenSim
environments are reported to leak over long runs. A step that never returns (a hung
integration) cannot be cut short from inside the process: the rollout pool's timeout is
the guard there.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import opensim
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.topology import MJCF_BODIES, topology_for
from gaitforge.workers.scenes import Scene, plan_pruning
from gaitforge.workers.sim.base import (
    HEALTHY,
    MAX_SPEED,
    BodyPose,
    CompileReport,
    Health,
    Pose,
    Reflex,
    SimState,
    check_pose_names,
)
from gaitforge.workers.sim.opensim.build import (
    PARKED,
    PUSH,
    build_model,
    quiet_opensim_log,
)
from gaitforge.workers.sim.opensim.drawing import (
    body_frames,
    ground_normal_force,
    muscle_paths,
    vec3,
)
from gaitforge.workers.sim.opensim.manager import new_manager
from gaitforge.workers.sim.opensim.size import full_plan, model_size

logger = logging.getLogger(__name__)

UP, FORWARD = 1, 0
"""Neutral bodies are Y-up and face +X."""


class OpenSimSimulator:
    """A scene on OpenSim. Pickles as its scene plus its state vector."""

    def __init__(self, scene: Scene, rebuild_every: int | None = None) -> None:
        quiet_opensim_log()
        if scene.body in MJCF_BODIES:
            raise ValueError(f"body {scene.body!r}: OpenSim runs neutral bodies only")
        self.scene = scene
        self.rebuild_every = rebuild_every or scene.opensim.rebuild_every
        self.up_axis, self.forward_axis = UP, FORWARD
        self._body = load_body(scene.body)
        topology = topology_for(scene.body)
        self._plan = plan_pruning(scene, topology)
        self.dof_names = list(self._plan.kept_dofs)
        self.muscle_names = list(self._plan.kept_muscles)
        self.foot_names = sorted(topology.feet)
        self._initial = {**topology.root_defaults, **topology.dof_defaults}
        root = self._body.ordered_joints()[0]
        self._lift_dof = next(
            (d.name for d in root.dofs if d.type == "slide" and abs(d.axis[UP]) > 0.999), None
        )
        self._ranges = {
            d.name: (d.limit.range if d.limit else d.range)
            for j in self._body.joints
            for d in j.dofs
        }
        """Each dof's range as MuJoCo enforces it (the passive limit's, else the dof's):
        ``set_pose`` clips to it, so both backends start from the same pose."""
        self._forward_dof = next(
            (d.name for d in root.dofs if d.type == "slide" and abs(d.axis[FORWARD]) > 0.999),
            None,
        )
        self.profile = scene.profile("opensim")
        self._rng = np.random.default_rng(0)
        self._episodes = 0
        self.rebuilds = 0
        self._build()
        self.report = CompileReport(
            scene=scene.name,
            backend="opensim",
            body=scene.body,
            profile=self.profile,
            plan=self._plan,
            size_full=model_size(build_model(self._body, full_plan(topology))),
            size=model_size(self._built),
            mass=self._body.total_mass,
            dropped_joints=list(self._plan.locked_dofs),
        )

    # ---- building ---------------------------------------------------------------------

    def _build(self) -> None:
        built = build_model(
            self._body,
            self._plan,
            tendon=self.scene.opensim.tendon,
            obstacles=self._plan.obstacles,
            push=self.scene.pushes is not None,
        )
        self._built = built
        self.model = built.model
        self._foot_forces = built.foot_forces
        self._obstacle_geometry = built.obstacle_geometry
        self._obstacles = np.zeros((len(built.obstacle_geometry), 3))
        self._obstacles[:, 0] = PARKED
        self.osim_state = self.model.initSystem()
        self._bind()

    def _bind(self) -> None:
        """Look up the components read or set every step (after each ``initSystem``)."""
        controller = opensim.PrescribedController.safeDownCast(
            self.model.getControllerSet().get("excitations")
        )
        functions = controller.upd_ControlFunctions()
        self._controls = [
            opensim.Constant.safeDownCast(functions.get(i)) for i in range(functions.getSize())
        ]
        self._push: list[opensim.Constant] = []
        if self.scene.pushes is not None:
            push = opensim.PrescribedForce.safeDownCast(self.model.getForceSet().get(PUSH))
            functions = push.upd_forceFunctions()
            self._push = [opensim.Constant.safeDownCast(functions.get(i)) for i in range(3)]
        coords = self.model.getCoordinateSet()
        self._coords = {c: coords.get(c) for c in [*self._initial] if coords.contains(c)}
        self._kept = [self._coords[d] for d in self.dof_names]
        muscles = self.model.getMuscles()
        self._muscles = [muscles.get(m) for m in self.muscle_names]
        self._pelvis = self.model.getBodySet().get("pelvis")
        forces = self.model.getForceSet()
        self._foot_force_objs = [
            [forces.get(name) for name in self._foot_forces.get(foot, [])]
            for foot in self.foot_names
        ]
        self._foot_spheres = [
            (self.model.getBodySet().get(c.segment), opensim.Vec3(*c.location), c.radius)
            for c in self._body.contact_spheres
            if c.name in self._plan.contact_geoms and c.part == "foot"
        ]
        self._sphere_feet = [
            c.foot
            for c in self._body.contact_spheres
            if c.name in self._plan.contact_geoms and c.part == "foot"
        ]

    # ---- protocol -----------------------------------------------------------------------

    def reset(self, seed: int) -> None:
        self._episodes += 1
        if self._episodes > 1 and (self._episodes - 1) % self.rebuild_every == 0:
            self._build()
            self.rebuilds += 1
        self._rng = np.random.default_rng(seed)
        self._place_obstacles()
        state = self.model.initializeState()
        noise = self.scene.init_noise
        for name, coord in self._coords.items():
            value = self._initial[name]
            if name in self.dof_names:
                value += self._rng.uniform(-noise, noise)
            coord.setValue(state, value, False)
        self._touch_floor(state)
        for control in (*self._controls, *self._push):
            control.setValue(0.0)
        for muscle in self._muscles:
            muscle.setActivation(state, 0.01)
        self.model.equilibrateMuscles(state)
        self.osim_state = state

    def step(self, excitations: np.ndarray, duration: float) -> Health:
        health, _ = self._integrate(excitations, duration, None)
        return health

    def step_reflex(
        self, reflex: Reflex, duration: float, updates: int
    ) -> tuple[np.ndarray, Health]:
        total = np.zeros(len(self._muscles))
        health, done, manager = Health(HEALTHY), 0, None
        for done in range(1, updates + 1):  # noqa: B007 (the count is read after the loop)
            state = self.osim_state
            q = np.array([c.getValue(state) for c in self._kept])
            qd = np.array([c.getSpeedValue(state) for c in self._kept])
            excitation = reflex(q, qd)
            total += excitation
            health, manager = self._integrate(excitation, duration / updates, manager)
            if not health.ok:
                break
        return total / done, health

    def _integrate(
        self, excitations: np.ndarray, duration: float, manager: opensim.Manager | None
    ) -> tuple[Health, opensim.Manager | None]:
        """Set the excitations (n_muscles,), clipped to [0, 1], and integrate ``duration`` s
        on: with ``manager`` where one is going on in this control step, else with a new one
        from the current state. Returns the health and the Manager to go on with."""
        excitations = np.clip(np.nan_to_num(excitations, nan=0.0), 0.0, 1.0)
        for control, value in zip(self._controls, excitations, strict=True):
            control.setValue(float(value))
        start = time.perf_counter()
        end_time = self.osim_state.getTime() + duration
        try:
            manager = manager or new_manager(self.model, self.profile, self.osim_state)
            state = manager.integrate(end_time)
        except RuntimeError as exc:
            logger.info("opensim integration failed: %s", str(exc).strip().splitlines()[-1])
            return Health("opensim_integrator_failed"), manager
        # integrate() returns a reference into its Manager: the previous Manager, and the
        # state it owned, are freed only here, once nothing reads that state any more.
        self._stepper, self.osim_state = manager, state
        if time.perf_counter() - start > self.scene.opensim.step_wall_limit_s:
            return Health("opensim_wall_time"), manager
        y = self.osim_state.getY().to_numpy()
        if not np.isfinite(y).all():
            return Health("nan_state"), manager
        if np.abs(self.osim_state.getU().to_numpy()).max(initial=0.0) > MAX_SPEED:
            return Health("diverged_speed"), manager
        return Health(HEALTHY), manager

    def moment_arms(self) -> np.ndarray:
        state = self.osim_state
        self.model.realizePosition(state)
        return np.array([[m.computeMomentArm(state, c) for c in self._kept] for m in self._muscles])

    def muscle_sensors(self) -> tuple[np.ndarray, np.ndarray]:
        """See ``Simulator.muscle_sensors``: OpenSim's normalised fibre length and tendon force
        over the maximum isometric force."""
        state = self.osim_state
        self.model.realizeDynamics(state)
        length = np.array([m.getNormalizedFiberLength(state) for m in self._muscles])
        force = np.array([m.getTendonForce(state) for m in self._muscles])
        force /= np.array([m.getMaxIsometricForce() for m in self._muscles])
        return length, force

    def state(self) -> SimState:
        state = self.osim_state
        self.model.realizeDynamics(state)
        pelvis = self._pelvis
        rotation = pelvis.getTransformInGround(state).R()
        up = np.array([rotation.get(i, UP) for i in range(3)])
        forward = np.array([rotation.get(i, FORWARD) for i in range(3)])
        velocity = pelvis.getVelocityInGround(state)
        feet = [sum(ground_normal_force(f, state) for f in foot) for foot in self._foot_force_objs]
        return SimState(
            time=state.getTime(),
            dof_pos=np.array([c.getValue(state) for c in self._kept]),
            dof_vel=np.array([c.getSpeedValue(state) for c in self._kept]),
            pelvis_pos=vec3(pelvis.getPositionInGround(state)),
            pelvis_up=up,
            pelvis_forward=forward,
            pelvis_vel=vec3(velocity.get(1)),
            pelvis_angvel=vec3(velocity.get(0)),
            activations=np.array([m.getActivation(state) for m in self._muscles]),
            foot_forces=np.array(feet),
        )

    def set_pose(self, pose: Pose) -> None:
        """See ``Simulator.set_pose``: coordinate values (clipped to the dof's limit range, as
        on MuJoCo) and speeds by name (root: ``pelvis_tilt`` (``_list``, ``_rotation``) and
        the up and forward slides, which OpenSim's planar root expresses in the ground
        frame), then muscles equilibrated."""
        check_pose_names(pose, self.scene.body, self.dof_names, self._plan.locked_dofs)
        state = self.osim_state
        values = {}
        for name, value in pose.coordinates.items():
            lo, hi = self._ranges.get(name, (-np.inf, np.inf))
            inside = lo <= value <= hi  # at a limit the joint rests there, as on MuJoCo
            speed = pose.speeds.get(name, 0.0) if inside else 0.0
            values[name] = (float(np.clip(value, lo, hi)), speed)
        rates = pose.pelvis_angular_speed
        root = {
            "pelvis_tilt": (pose.pelvis_pitch, rates[0]),
            "pelvis_list": (pose.pelvis_list, rates[1]),
            "pelvis_rotation": (pose.pelvis_rotation, rates[2]),
        }
        for name, (value, speed) in [*values.items(), *root.items()]:
            coord = self._coords.get(name)
            if coord is not None and (name in self.dof_names or name in root):
                coord.setValue(state, float(value), False)
                coord.setSpeedValue(state, float(speed))
        if self._forward_dof in self._coords:
            self._coords[self._forward_dof].setSpeedValue(state, pose.forward_speed)
        lift = self._coords.get(self._lift_dof) if self._lift_dof else None
        if lift is not None:
            lift.setSpeedValue(state, pose.vertical_speed)
            self.model.realizePosition(state)
            height = self._pelvis.getPositionInGround(state).get(UP)
            lift.setValue(state, lift.getValue(state) + pose.pelvis_height - height, False)
            self._touch_floor(state, raise_only=True)
        self.model.equilibrateMuscles(state)

    def push(self, force: np.ndarray) -> None:
        if not self._push:
            raise ValueError(f"scene {self.scene.name!r} has no pushes")
        for component, value in zip(self._push, force, strict=True):
            component.setValue(float(value))

    def foot_positions(self) -> dict[str, np.ndarray]:
        spheres = self.contact_spheres()
        return {
            foot: s[:, :3].mean(axis=0) if len(s) else np.full(3, np.nan)
            for foot, s in spheres.items()
        }

    def obstacles(self) -> np.ndarray:
        return self._obstacles.copy()

    def get_state(self) -> dict[str, np.ndarray]:
        s = self.osim_state
        return {
            "time": np.array([s.getTime()]),
            "y": s.getY().to_numpy(),
            "controls": np.array([c.getValue() for c in self._controls]),
            "obstacles": self._obstacles.copy(),
            "episodes": np.array([self._episodes]),
        }

    def set_state(self, saved: dict[str, np.ndarray]) -> None:
        self._episodes = int(saved["episodes"][0])
        self._set_obstacles(saved["obstacles"])
        state = self.model.initializeState()
        state.setTime(float(saved["time"][0]))
        state.setY(opensim.Vector.createFromMat(saved["y"]))
        for control, value in zip(self._controls, saved["controls"], strict=True):
            control.setValue(float(value))
        self.osim_state = state

    def poison(self) -> None:
        speeds = self.osim_state.updU()
        for i in range(speeds.size()):
            speeds.set(i, float("nan"))

    # ---- read-outs for drawing ----------------------------------------------------------

    def body_frames(self) -> dict[str, BodyPose]:
        return body_frames(self.model, self.osim_state)

    def muscle_paths(self) -> dict[str, np.ndarray]:
        """``GeometryPath.getCurrentPath``: path points active now, wrap points included."""
        return muscle_paths(self.model, self.osim_state, self.muscle_names, self._muscles)

    def contact_spheres(self) -> dict[str, np.ndarray]:
        state = self.osim_state
        self.model.realizePosition(state)
        spheres: dict[str, list] = {foot: [] for foot in self.foot_names}
        for foot, (body, where, radius) in zip(self._sphere_feet, self._foot_spheres, strict=True):
            if foot in spheres:
                centre = vec3(body.findStationLocationInGround(state, where))
                spheres[foot].append([*centre, radius])
        return {foot: np.array(s, dtype=float).reshape(-1, 4) for foot, s in spheres.items()}

    def coordinates(self) -> dict[str, float]:
        state = self.osim_state
        coords = self.model.getCoordinateSet()
        return {
            coords.get(i).getName(): coords.get(i).getValue(state) for i in range(coords.getSize())
        }

    def __getstate__(self) -> dict:
        return {"scene": self.scene, "rebuild_every": self.rebuild_every, "saved": self.get_state()}

    def __setstate__(self, pickled: dict) -> None:
        self.__init__(pickled["scene"], pickled["rebuild_every"])  # type: ignore[misc]
        self.set_state(pickled["saved"])

    # ---- helpers ----------------------------------------------------------------------

    def _touch_floor(self, state: opensim.State, raise_only: bool = False) -> None:
        """Shift the pelvis height so the lowest foot sphere just touches the floor (with
        ``raise_only``, only if it lies inside the floor)."""
        lift = self._coords.get(self._lift_dof) if self._lift_dof else None
        if lift is None or not self._foot_spheres:
            return
        self.model.realizePosition(state)
        lowest = min(
            body.findStationLocationInGround(state, where).get(UP) - radius
            for body, where, radius in self._foot_spheres
        )
        if lowest < 0.0 or not raise_only:
            lift.setValue(state, lift.getValue(state) - lowest, False)

    def _place_obstacles(self) -> None:
        spec = self.scene.obstacles
        if spec is not None and self._obstacle_geometry:
            self._set_obstacles(spec.draw(self._rng))

    def _set_obstacles(self, obstacles: np.ndarray) -> None:
        """Move the obstacle spheres ([n, 3]: forward, height, radius, m); re-inits the system."""
        if not len(obstacles):
            return
        geometry = self.model.getContactGeometrySet()
        for name, (ahead, height, radius) in zip(self._obstacle_geometry, obstacles, strict=True):
            sphere = opensim.ContactSphere.safeDownCast(geometry.get(name))
            sphere.set_location(opensim.Vec3(float(ahead), float(height), 0.0))
            sphere.setRadius(float(radius))
        self._obstacles = np.array(obstacles, dtype=float)
        self.osim_state = self.model.initSystem()
        self._bind()
