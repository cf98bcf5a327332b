"""The reference pose of an episode with the gait clock, for drawing beside the body (MCAP
recordings, videos): the motion's state at the episode's current phase (``env.reference_state()``,
mirrored when the episode is) put on a second copy of the body's kinematics, the scene's own
MuJoCo model with its own data (``MujocoSimulator.set_pose``), so that the reference
skeleton has exactly the body's bones.

The reference is translated with the body along the ground: its pelvis stands where the
body's pelvis is along the forward and lateral axes, at the motion's pelvis height, so the
two skeletons overlap where the body follows the motion and part where it does not.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
from gaitforge.workers.sim.base import BodyPose

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv
    from gaitforge.workers.motions import MotionState
    from gaitforge.workers.sim.base import Pose
    from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

logger = logging.getLogger(__name__)


def has_clock(env: MuscleEnv) -> bool:
    """Whether ``env``'s scene has a gait clock (``task.clock``), whose reference state can
    be drawn."""
    return getattr(env.scene.task, "clock", None) is not None


def pose_of(state: MotionState) -> Pose:
    """A motion's state as a simulator ``Pose`` (same names, units and conventions)."""
    from gaitforge.workers.sim.base import Pose

    return Pose(
        coordinates=dict(state.joints),
        speeds=dict(state.joint_speeds),
        pelvis_height=state.pelvis_height,
        pelvis_pitch=state.pelvis_pitch,
        pelvis_list=state.pelvis_list,
        pelvis_rotation=state.pelvis_rotation,
        pelvis_angular_speed=tuple(state.pelvis_angular_speed),  # type: ignore[arg-type]
        forward_speed=state.forward_speed,
        vertical_speed=state.pelvis_vertical_speed,
    )


class ReferenceBody:
    """A second copy of ``env``'s body kinematics posed at ``env.reference_state()``.

    Raises:
        ValueError: the scene has no MuJoCo model of its body (one line).
    """

    def __init__(self, env: MuscleEnv) -> None:
        from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator  # lazy: compiles a model

        if "mujoco" not in env.scene.backends:
            raise ValueError(
                f"scene {env.scene.name!r} has no MuJoCo model of its body (backends "
                f"{env.scene.backends}): its reference pose cannot be drawn"
            )
        self.sim: MujocoSimulator = MujocoSimulator(env.scene)
        self.sim.reset(0)
        self._up = self.sim.up_axis
        self._pelvis = "pelvis"

    def frames(self, env: MuscleEnv) -> dict[str, BodyPose] | None:
        """World pose of every body of the reference (the simulator's world frame, as
        ``Simulator.body_frames``), translated with ``env``'s pelvis along the ground; None
        when the env has no reference now (no gait clock, or before a reset)."""
        state = env.reference_state() if hasattr(env, "reference_state") else None
        if state is None:
            return None
        self.sim.set_pose(pose_of(state))
        frames = self.sim.body_frames()
        here = env.sim.state().pelvis_pos
        there = frames[self._pelvis].position if self._pelvis in frames else np.zeros(3)
        delta = np.where(np.isfinite(here), here - there, 0.0)
        delta[self._up] = 0.0
        return {
            name: BodyPose(f.position + delta, f.quaternion, f.parent) for name, f in frames.items()
        }
