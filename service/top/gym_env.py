"""The env ``gymnasium.make("gaitforge/...")`` makes: :class:`~gaitforge.workers.env.MuscleEnv`
with Gymnasium's rendering and, for libraries that expect it, actions in [-1, 1].

- ``render_mode="rgb_array"``: ``render()`` returns [height, width, 3] uint8 RGB frames of
  the current state, drawn offscreen as ``gaitforge evaluate --video`` draws them
  (``learner.evaluation.video.FrameRenderer``: the pelvis tracked from the side, muscles
  coloured by activation, the skeleton), for Gymnasium's frame wrappers (``RecordVideo``
  once moviepy is installed). ``gym.make(..., render_mode="human")`` shows them in a window
  through Gymnasium's ``HumanRendering`` wrapper, where a display and pygame are at hand.
- ``action_range="symmetric"``: the action space is [-1, 1] (Stable-Baselines3 warns on any
  other), mapped to the scene's [0, 1] excitations or targets as ``(a + 1) / 2``;
  ``"unit"`` (the default) keeps [0, 1].
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import gymnasium as gym
import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene

if TYPE_CHECKING:
    from gaitforge.learner.evaluation.video import FrameRenderer

RENDER_MODES = ("rgb_array",)
ACTION_RANGES = ("unit", "symmetric")


class GymMuscleEnv(MuscleEnv):
    """A scene's env for Gymnasium users (see the module's docstring).

    Args:
        scene: a catalogue scene, a composition (``base+option+...``), a scene YAML or a
            ``Scene``.
        backend: "mujoco" or "opensim".
        render_mode: None or "rgb_array".
        action_range: "unit" ([0, 1]) or "symmetric" ([-1, 1]).
        width, height: pixels of a rendered frame.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 25}  # noqa: RUF012

    def __init__(
        self,
        scene: str | Path | Scene,
        backend: str = "mujoco",
        render_mode: Literal["rgb_array"] | None = None,
        action_range: Literal["unit", "symmetric"] = "unit",
        width: int = 480,
        height: int = 360,
    ) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(
                f"render_mode {render_mode!r}: allowed {list(RENDER_MODES)} or None (for a "
                "window, gymnasium.make(..., render_mode='human') wraps rgb_array)"
            )
        if action_range not in ACTION_RANGES:
            raise ValueError(f"action_range {action_range!r}: allowed {list(ACTION_RANGES)}")
        super().__init__(scene if isinstance(scene, Scene) else str(scene), backend)
        self.metadata = {**self.metadata, "render_fps": self.scene.control_hz}
        self.render_mode = render_mode
        self.action_range = action_range
        self._size = (width, height)
        self._frames: FrameRenderer | None = None
        if action_range == "symmetric":
            shape = self.action_space.shape
            self.action_space = gym.spaces.Box(-1.0, 1.0, shape, dtype=np.float32)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self.action_range == "symmetric":
            action = (np.asarray(action, dtype=np.float64) + 1.0) / 2.0
        return super().step(action)

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        """[height, width, 3] uint8 RGB image of the current state with ``rgb_array``;
        None without a render mode."""
        if self.render_mode is None:
            return None
        if self._frames is None:
            from gaitforge.learner.evaluation.video import FrameRenderer  # lazy: a GL context

            self._frames = FrameRenderer(self, *self._size)
        return self._frames.render(self)

    def close(self) -> None:
        if self._frames is not None:
            self._frames.close()
            self._frames = None
        super().close()
