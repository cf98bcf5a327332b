"""The two sides of a conversion measure: the original OpenSim model and the MuJoCo model
built from the body, each posed by coordinate name and read out (centres of mass, muscle
lengths, moment arms, tendon forces) in the same terms.

Units: metres, radians, newtons.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import opensim
from gaitforge.workers.bodies.osim_basics import joints_between
from gaitforge.workers.bodies.osim_import import read_model_file
from gaitforge.workers.sim.mujoco.couplings import CARRIER_SUFFIX
from gaitforge.workers.sim.mujoco.lock import coupled_qpos
from gaitforge.workers.sim.opensim.build import quiet_opensim_log
from gaitforge.workers.spec_io import SpecError, shorten

logger = logging.getLogger(__name__)


# --------------------------------------------------------------------------- OpenSim


def load_opensim_model(path: Path) -> Any:
    """``opensim.Model`` read from ``path``, OpenSim's log silenced.

    Raises:
        SpecError: the file is missing, unreadable, not an OpenSim model, or one OpenSim
            cannot load (one line naming it and why).
    """
    quiet_opensim_log()
    path = Path(path)
    if not path.exists():
        raise SpecError(f"{path}: file not found")
    if not path.is_file():
        raise SpecError(f"{path}: not a file")
    _, xml_problem = read_model_file(path)  # an older format OpenSim upgrades as it loads
    try:
        return opensim.Model(str(path))
    except Exception as exc:  # OpenSim raises RuntimeError with a multi-line message
        if xml_problem is not None:
            raise SpecError(f"{path}: {xml_problem}; OpenSim cannot load it") from None
        reason = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        raise SpecError(f"{path}: OpenSim cannot load the model: {shorten(reason, 300)}") from None


class OpenSimSide:
    """The original model, posed by coordinate name.

    Every coordinate is unlocked unless named in ``locked`` (those are locked at their
    defaults), so that any pose can be set."""

    def __init__(self, path: Path, locked: frozenset[str] = frozenset()) -> None:
        self.model = load_opensim_model(path)
        coordinate_set = self.model.getCoordinateSet()
        self.default_locked: set[str] = set()  # the coordinates the file locks
        for i in range(coordinate_set.getSize()):
            coordinate = coordinate_set.get(i)
            if coordinate.getDefaultLocked():
                self.default_locked.add(coordinate.getName())
            coordinate.setDefaultLocked(coordinate.getName() in locked)
        self.state = self.model.initSystem()
        self.coordinates = {
            coordinate_set.get(i).getName(): coordinate_set.get(i)
            for i in range(coordinate_set.getSize())
        }
        self.couplers: list[tuple[str, list[str], Any]] = []
        constraints = self.model.getConstraintSet()
        for i in range(constraints.getSize()):
            coupler = opensim.CoordinateCouplerConstraint.safeDownCast(constraints.get(i))
            if coupler is None or not coupler.get_isEnforced():
                continue
            names = coupler.getIndependentCoordinateNames()
            self.couplers.append(
                (
                    coupler.getDependentCoordinateName(),
                    [names.get(k) for k in range(names.getSize())],
                    coupler.getFunction(),
                )
            )
        dependent = {d for d, _, _ in self.couplers}
        self.free = [name for name in self.coordinates if name not in dependent]
        self.driver_of = {d: independents[0] for d, independents, _ in self.couplers}
        muscles = self.model.getMuscles()
        self.muscles = {muscles.get(i).getName(): muscles.get(i) for i in range(muscles.getSize())}
        bodies = self.model.getBodySet()
        self.bodies = {bodies.get(i).getName(): bodies.get(i) for i in range(bodies.getSize())}

    def defaults(self) -> dict[str, float]:
        """Each free coordinate's default value (rad or m)."""
        return {name: self.coordinates[name].getDefaultValue() for name in self.free}

    def ranges(self) -> dict[str, tuple[float, float]]:
        """Each free coordinate's range (rad or m)."""
        return {
            name: (self.coordinates[name].getRangeMin(), self.coordinates[name].getRangeMax())
            for name in self.free
        }

    def rotational(self, name: str) -> bool:
        return self.coordinates[name].getMotionType() == opensim.Coordinate.Rotational

    def set_pose(self, values: Mapping[str, float]) -> None:
        """Free coordinates to ``values`` (rad, m), coupled ones after them; positions
        realised."""
        for name, value in values.items():
            if not self.coordinates[name].getLocked(self.state):
                self.coordinates[name].setValue(self.state, float(value), False)
        for dependent, independents, function in self.couplers:
            x = opensim.Vector(len(independents), 0.0)
            for k, name in enumerate(independents):
                x.set(k, self.coordinates[name].getValue(self.state))
            self.coordinates[dependent].setValue(self.state, function.calcValue(x), False)
        self.model.realizePosition(self.state)

    def centres_of_mass(self, names: list[str]) -> np.ndarray:
        """[len(names), 3] world positions of the segments' centres of mass, m."""
        return np.array(
            [
                self.bodies[n]
                .findStationLocationInGround(self.state, self.bodies[n].getMassCenter())
                .to_numpy()
                for n in names
            ]
        )

    def spanned(self) -> dict[str, list[str]]:
        """Each muscle's free coordinates: those of the joints between the bodies its path
        points (and moving or conditional points' coordinates) attach to, a coupled
        coordinate replaced by its driver."""
        spans: dict[str, list[str]] = {}
        for name, muscle in self.muscles.items():
            points = muscle.getGeometryPath().getPathPointSet()
            segments: set[str] = set()
            extra: list[str] = []
            for k in range(points.getSize()):
                point = points.get(k)
                segments.add(point.getParentFrame().findBaseFrame().getName())
                moving = opensim.MovingPathPoint.safeDownCast(point)
                if moving is not None:
                    extra += [moving.getXCoordinate().getName()]
                conditional = opensim.ConditionalPathPoint.safeDownCast(point)
                if conditional is not None:
                    extra += [conditional.getCoordinate().getName()]
            crossed = [
                joint.get_coordinates(k).getName()
                for joint in joints_between(self.model, segments)
                for k in range(joint.numCoordinates())
            ]
            free = [self.driver_of.get(c, c) for c in [*crossed, *extra]]
            spans[name] = [c for c in dict.fromkeys(free) if c in self.free]
        return spans

    def tendon_forces(self, activation: float | None) -> dict[str, float]:
        """Each muscle's tendon force (N) at zero velocity, its fibre in equilibrium, all at
        ``activation`` (None: each at its own minimum); NaN where equilibrium fails."""
        for name, muscle in self.muscles.items():
            level = self.minimum_activation(name) if activation is None else activation
            muscle.setActivation(self.state, level)
        self.state.updU().setToZero()
        forces: dict[str, float] = {}
        failed: set[str] = set()
        for name, muscle in self.muscles.items():
            try:
                muscle.computeEquilibrium(self.state)
            except Exception as exc:  # OpenSim raises RuntimeError when it cannot converge
                logger.info("OpenSim: %s: no fibre equilibrium: %s", name, exc)
                failed.add(name)
        self.model.realizeDynamics(self.state)
        for name, muscle in self.muscles.items():
            forces[name] = math.nan if name in failed else muscle.getTendonForce(self.state)
        return forces

    def minimum_activation(self, name: str) -> float:
        """The muscle's minimum activation (Millard's and Thelen's property; 0.01 else)."""
        muscle = self.muscles[name]
        for kind in (opensim.Millard2012EquilibriumMuscle, opensim.Thelen2003Muscle):
            concrete = kind.safeDownCast(muscle)
            if concrete is not None:
                return float(concrete.get_minimum_activation())
        return 0.01


# --------------------------------------------------------------------------- MuJoCo


class MujocoSide:
    """The model built from the body, posed by joint name."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.joints = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j): j for j in range(model.njnt)
        }
        self.tendons = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, t): t for t in range(model.ntendon)
        }
        self.actuators = {
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a): a for a in range(model.nu)
        }
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]
        self.bodies = {  # a moving point's carrier is part of its muscle's path, not a segment
            name: b for b, name in enumerate(names) if not name.endswith(CARRIER_SUFFIX)
        }
        self._jacobian = np.zeros((model.ntendon, model.nv))

    def set_pose(self, values: Mapping[str, float]) -> None:
        """Joints named in ``values`` to them (rad, m), the others at ``qpos0``, coupled ones
        after their drivers; positions and tendons computed; velocities zero."""
        qpos = self.model.qpos0.copy()
        for name, value in values.items():
            joint = self.joints.get(name)
            if joint is not None:
                qpos[self.model.jnt_qposadr[joint]] = value
        self.data.qpos[:] = coupled_qpos(self.model, qpos)
        self.data.qvel[:] = 0.0
        mujoco.mj_fwdPosition(self.model, self.data)

    def centres_of_mass(self, names: list[str]) -> np.ndarray:
        """[len(names), 3] world positions of the bodies' centres of mass, m."""
        return np.array([self.data.xipos[self.bodies[n]] for n in names])

    def lengths(self) -> np.ndarray:
        """[ntendon] tendon lengths at the current pose, m."""
        return np.array(self.data.ten_length)

    def moment_arms(self, coordinate: str) -> np.ndarray:
        """[ntendon] ``-dL/dq`` about the free joint ``coordinate`` at the current pose, the
        joints it drives folded in (m per rad, or m/m)."""
        mujoco.mju_sparse2dense(
            self._jacobian,
            self.data.ten_J,
            self.model.ten_J_rownnz,
            self.model.ten_J_rowadr,
            self.model.ten_J_colind,
        )
        return -(self._jacobian @ self._chain(coordinate))

    def _chain(self, coordinate: str) -> np.ndarray:
        """[nv] ``dq_dof / dq_coordinate`` at the current pose: 1 at the coordinate's own dof,
        the polynomial's slope at every joint an equality couples to it."""
        model = self.model
        driver = self.joints[coordinate]
        column = np.zeros(model.nv)
        column[model.jnt_dofadr[driver]] = 1.0
        for i in range(model.neq):
            if model.eq_type[i] != mujoco.mjtEq.mjEQ_JOINT or model.eq_obj2id[i] != driver:
                continue
            coefficients = model.eq_data[i, :5]
            x = self.data.qpos[model.jnt_qposadr[driver]] - model.qpos0[model.jnt_qposadr[driver]]
            slope = np.polyval(np.polyder(coefficients[::-1]), x)
            column[model.jnt_dofadr[model.eq_obj1id[i]]] += slope
        return column

    def tendon_forces(self, activations: Mapping[str, float]) -> dict[str, float]:
        """Each muscle actuator's tendon force (N, pulling positive) at the current pose,
        zero velocity, activation as given by name."""
        for name, level in activations.items():
            actuator = self.actuators.get(name)
            if actuator is None:
                continue
            address = self.model.actuator_actadr[actuator]
            if address >= 0:
                self.data.act[address] = level
            self.data.ctrl[actuator] = level
        mujoco.mj_forward(self.model, self.data)
        return {
            name: -float(self.data.actuator_force[self.actuators[name]])
            for name in activations
            if name in self.actuators
        }
