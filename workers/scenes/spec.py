"""The Scene spec: what a training scene is made of, validated once when it is loaded, and
resolved on the driver (``Scene.resolved``) before it goes anywhere else."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from gaitforge.workers.bodies.topology import MJCF_BODIES
from gaitforge.workers.scenes import saved_profiles
from gaitforge.workers.scenes.action import ActionSpec
from gaitforge.workers.scenes.backend_options import MujocoOptions, OpenSimOptions
from gaitforge.workers.scenes.clock import Clock
from gaitforge.workers.scenes.imitate import Imitate, check_imitation
from gaitforge.workers.scenes.migration import read_older_layout
from gaitforge.workers.scenes.profiles import (
    BACKENDS,
    NAMED_PROFILES,
    Backend,
    Fidelity,
    FidelityProfile,
    check_profile,
)
from gaitforge.workers.spec_types import MAX_NAME_LENGTH, MAX_TEXT_LENGTH, SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field, model_validator

NonNegative = Annotated[float, Field(ge=0)]
SCENE_NAME_PATTERN = r"^[a-z0-9][a-z0-9-]*(\+[a-z0-9][a-z0-9-]*)*$"
"""a scene's name: a catalogue base, or ``base+option+...`` for a composed scene"""
Range = Annotated[tuple[float, float], Field(strict=False)]
"""(low, high), written as a list ``[low, high]``; each a finite number"""


class _Strict(BaseModel):
    """A part of a scene: unknown fields are errors, values frozen, numbers strict and finite
    (``workers.spec_types.SPEC_VALUES``)."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)


class Keep(_Strict):
    """What the scene keeps; everything else is locked (joints) or removed (muscles)."""

    joints: list[str] | Literal["all"] = Field(
        default="all", description="dofs that move; the others are welded at their default"
    )
    muscles: list[str] | Literal["all"] = Field(
        default="all", description="muscles to keep (those spanning only locked dofs go anyway)"
    )
    lock_at: dict[str, float] = Field(
        default_factory=dict, description="value (rad or m) for locked dofs instead of default"
    )
    contacts: Literal["feet", "all"] = Field(
        default="feet", description="which body geoms may touch the ground and obstacles"
    )
    visuals: bool = Field(
        default=False,
        description="keep geoms and sites that only draw (bone meshes, markers); for rendering",
    )


class Terrain(_Strict):
    type: Literal["flat"] = "flat"
    friction: NonNegative = 0.9


class Obstacles(_Strict):
    """Spheres half buried in the ground ahead of the body, re-placed every episode."""

    count: Annotated[int, Field(ge=0, le=50)] = 10
    x_range: Range = Field(default=(1.0, 5.0), description="m ahead of start")
    radius_range: Range = Field(default=(0.05, 0.1), description="m")
    height_range: Range = Field(
        default=(-0.5, 0.5), description="centre height in radii above the ground"
    )
    observe_ahead: Annotated[int, Field(ge=1, le=10)] = Field(
        default=1, description="spheres observed ahead of the pelvis, nearest first"
    )

    @model_validator(mode="after")
    def _ranges(self) -> Obstacles:
        for name in ("x_range", "radius_range", "height_range"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name} must be (low, high), got {(lo, hi)}")
        if self.radius_range[0] <= 0:
            raise ValueError("radius_range must be positive")
        return self

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """[count, 3]: forward position (m, sorted), centre height (m) and radius (m)."""
        radius = rng.uniform(*self.radius_range, self.count)
        ahead = np.sort(rng.uniform(*self.x_range, self.count))
        height = radius * rng.uniform(*self.height_range, self.count)
        return np.column_stack([ahead, height, radius])


class Pushes(_Strict):
    """Random horizontal pushes on the pelvis's centre of mass, drawn anew each episode:
    each of a magnitude drawn from ``force_n``, in a direction drawn uniformly about the
    vertical, held for ``duration_s``; each starts a draw from ``every_s`` after the one
    before (the first, after the episode's start). They act at control-step boundaries:
    a push is held over the control steps that start within it."""

    force_n: Range = Field(description="N, each push's magnitude, drawn uniformly")
    duration_s: Annotated[float, Field(ge=0.01, le=10)] = Field(
        default=0.2, description="s each push is held (at least 0.01: a bound on the pushes drawn)"
    )
    every_s: Range = Field(
        default=(2.0, 3.0), description="s from one push's start to the next's, drawn uniformly"
    )

    @model_validator(mode="after")
    def _ranges(self) -> Pushes:
        for name in ("force_n", "every_s"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(
                    f"{name} must be (low, high) with 0 <= low <= high, got {(lo, hi)}"
                )
        if self.every_s[0] < self.duration_s:
            raise ValueError(
                f"every_s {self.every_s}: its low end must be at least duration_s "
                f"{self.duration_s} (pushes do not overlap)"
            )
        return self

    def draw(self, rng: np.random.Generator, episode_s: float) -> np.ndarray:
        """[n, 4]: each push's start and end (s), direction (rad about the vertical from
        the world's forward axis toward its right) and magnitude (N), for an episode of
        ``episode_s`` seconds."""
        pushes = []
        start = float(rng.uniform(*self.every_s))
        while start < episode_s:
            angle, force = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(*self.force_n)
            pushes.append((start, start + self.duration_s, angle, force))
            start += float(rng.uniform(*self.every_s))
        return np.array(pushes, dtype=float).reshape(-1, 4)


class RewardWeights(_Strict):
    """Weights of the named reward terms (see ``workers.rewards`` for each term's unit)."""

    forward: float = 0.0
    target_speed: float = 0.0
    overspeed: float = 0.0
    """charges running faster than the target only: with ``forward`` at weight f (per m, at
    control period dt) and this at w, the pay per step is highest at target + f dt / (2 w)
    m/s, and a start below the target is not charged (``target_speed`` charges it)"""
    effort: float = 0.0
    smoothness: float = 0.0
    upright: float = 0.0
    alive: float = 0.0
    reach: float = 0.0


class Task(_Strict):
    kind: Literal["locomotion", "reach"]
    target_speed: NonNegative | None = Field(default=None, description="m/s, locomotion")
    target_speed_range: Range | None = Field(
        default=None,
        description="m/s; drawn uniformly each episode in place of target_speed (observed and "
        "rewarded; the gait clock's main motion plays at tempo times drawn / target_speed)",
    )
    min_pelvis_height: float | None = Field(
        default=None, description="m; the episode terminates below it (a fall)"
    )
    reach_dof: str | None = Field(default=None, description="dof to bring to a target angle")
    reach_range: Range | None = Field(
        default=None, description="rad; target sampled uniformly each episode"
    )
    reward: RewardWeights = RewardWeights()
    clock: Clock | None = Field(
        default=None,
        description="the gait clock: the phase of a recorded gait, observed, and the base of "
        "joint-target actions (locomotion only)",
    )
    imitate: Imitate | None = Field(
        default=None, description="track the clock's motion (locomotion only; needs clock)"
    )

    @model_validator(mode="after")
    def _consistent(self) -> Task:
        if self.kind == "reach" and (self.reach_dof is None or self.reach_range is None):
            raise ValueError("a reach task needs reach_dof and reach_range")
        if self.clock is not None and self.kind != "locomotion":
            raise ValueError(
                f"clock: a gait clock needs a locomotion task (a body with a pelvis), "
                f"not kind {self.kind!r}"
            )
        check_imitation(self.imitate, self.clock)
        if self.kind == "locomotion" and self.min_pelvis_height is None:
            raise ValueError("a locomotion task needs min_pelvis_height")
        if self.reward.overspeed and not self.target_speed:
            raise ValueError(
                f"task.reward.overspeed {self.reward.overspeed}: the task has no target speed "
                "to run over (set target_speed, or the weight to 0)"
            )
        if self.target_speed_range is not None:
            low, high = self.target_speed_range
            if not self.target_speed or not 0 < low <= high:
                raise ValueError(
                    "target_speed_range must be (low, high) m/s with 0 < low <= high, on a "
                    f"task with target_speed > 0 (the clock's pace); got {(low, high)} with "
                    f"target_speed {self.target_speed}"
                )
        return self


class Scene(_Strict):
    """A scene: a body, what of it to keep, the world around it and the task."""

    name: str = Field(
        pattern=SCENE_NAME_PATTERN,
        max_length=MAX_NAME_LENGTH,
        description="a catalogue name, base+option+... for a composed scene",
    )
    description: str = Field(default="", max_length=MAX_TEXT_LENGTH)
    body: str = Field(
        max_length=MAX_NAME_LENGTH,
        description=f"a neutral body name or body file (.yaml), or one of {list(MJCF_BODIES)}",
    )
    backends: list[Backend] = Field(default_factory=lambda: ["mujoco"], min_length=1)
    keep: Keep = Keep()
    terrain: Terrain = Terrain()
    obstacles: Obstacles | None = None
    pushes: Pushes | None = Field(
        default=None, description="random horizontal pushes on the pelvis (the pushes option)"
    )
    task: Task
    control_hz: Annotated[float, Field(gt=0, le=1000)] = 100.0
    action: ActionSpec = Field(
        default_factory=ActionSpec,
        description="the policy's action: excitations, or joint targets for a reflex layer",
    )
    episode_s: Annotated[float, Field(gt=0, le=600)] = 10.0
    fidelity: Fidelity = "default"
    fidelity_tolerance: Annotated[float, Field(gt=0)] | None = Field(
        default=None, description="rad: RMS joint-angle error allowed with fidelity: auto"
    )
    fidelity_names: dict[Backend, str] = Field(
        default_factory=dict,
        description="set by Scene.resolved, for records: per backend, the name its profile "
        "was resolved from (built-in or saved name, 'auto: <saved name>')",
    )
    mujoco: MujocoOptions = Field(
        default_factory=MujocoOptions,
        description="how MuJoCo models contact and muscles (OpenSim: ignored)",
    )
    opensim: OpenSimOptions = Field(
        default_factory=OpenSimOptions,
        description="OpenSim's tendons and run bounds (MuJoCo: ignored)",
    )
    init_noise: NonNegative = Field(default=0.01, description="rad, m: uniform reset noise")

    @model_validator(mode="before")
    @classmethod
    def _older_layout(cls, raw: object) -> object:
        """Scene fields as older files and checkpoints wrote them, read as today's: the
        backend options at the top level move into ``mujoco`` and ``opensim``; a ``fault``
        of null goes (fault injection is a test hook, ``workers.sim.faults``); a retired
        setting at its former default goes, at any other value it is refused naming the field
        (``workers.scenes.migration``)."""
        return read_older_layout(raw) if isinstance(raw, dict) else raw

    @model_validator(mode="after")
    def _check(self) -> Scene:
        if self.body in MJCF_BODIES and "opensim" in self.backends:
            raise ValueError(f"backends: body {self.body!r} is MJCF and runs on MuJoCo only")
        for backend in self.backends:
            profile = self.profile(backend)
            steps = 1.0 / (self.control_hz * profile.timestep)
            if backend == "mujoco" and abs(steps - round(steps)) > 1e-6:
                raise ValueError(
                    f"fidelity.timestep {profile.timestep} s does not divide the control "
                    f"period 1/{self.control_hz} s"
                )
        if self.action.targets:
            self._check_reflex()
        if self.pushes is not None and self.task.kind != "locomotion":
            raise ValueError(
                f"pushes: they push a pelvis, and need a locomotion task, not {self.task.kind!r}"
            )
        return self

    def _check_reflex(self) -> None:
        chunks = self.action.reflex_hz / self.control_hz
        if chunks < 1 or abs(chunks - round(chunks)) > 1e-6:
            raise ValueError(
                f"action.reflex_hz {self.action.reflex_hz} must be a whole multiple of "
                f"control_hz {self.control_hz}"
            )
        if "mujoco" not in self.backends:
            return
        substeps = 1.0 / (self.action.reflex_hz * self.profile("mujoco").timestep)
        if abs(substeps - round(substeps)) > 1e-6:
            raise ValueError(
                f"action.reflex_hz {self.action.reflex_hz}: its period must be a whole number "
                f"of fidelity.timestep {self.profile('mujoco').timestep} s"
            )

    @property
    def reflex_chunks(self) -> int:
        """Reflex updates per control step (1 unless ``action.kind`` is joint_targets)."""
        if not self.action.targets:
            return 1
        return round(self.action.reflex_hz / self.control_hz)

    @property
    def steps_per_episode(self) -> int:
        return round(self.episode_s * self.control_hz)

    def profile(self, backend: str) -> FidelityProfile:
        """The concrete fidelity profile on ``backend``; raises ``ValueError`` if invalid.

        On an unresolved scene, a saved name or ``auto`` reads this machine's profile
        directory: only the driver should ask (see :meth:`resolved`).
        """
        return resolve_profile(self.fidelity, backend, self.name, self.fidelity_tolerance)[0]

    def profile_name(self, backend: str) -> str:
        """The fidelity profile's name on ``backend``, for records: a built-in or saved
        name, ``auto: <saved name>``, or ``custom`` for an explicit profile."""
        if self.is_resolved:
            return self.fidelity_names.get(backend, "custom")  # type: ignore[call-overload]
        _, name = resolve_profile(self.fidelity, backend, self.name, self.fidelity_tolerance)
        return name or "custom"

    @property
    def is_resolved(self) -> bool:
        """Whether the fidelity is concrete on every backend of the scene: one explicit
        profile, or one per backend (no name, no ``auto``: nothing to look up)."""
        fidelity = self.fidelity
        if isinstance(fidelity, FidelityProfile):
            return True
        return isinstance(fidelity, dict) and all(
            isinstance(fidelity.get(b), FidelityProfile)  # type: ignore[arg-type]
            for b in self.backends
        )

    def require_resolved(self, where: str) -> Scene:
        """This scene if it is resolved; else ``ValueError`` (one line) naming ``where``."""
        if not self.is_resolved:
            raise ValueError(
                f"{where}: scene {self.name!r} has fidelity {self.fidelity!r}, not resolved; "
                "call scene.resolved() on the driver, where the scene is loaded (worker nodes "
                "hold no saved profiles)"
            )
        return self

    def resolved(self) -> Scene:
        """This scene with its fidelity replaced by the concrete profile it names on each of
        its backends (built-in or saved name, ``auto``, a per-backend mapping of those);
        ``fidelity_names`` keeps the names. A resolved scene is returned as it is.

        Call it where the scene is loaded, on the driver: saved profiles are that machine's
        files, and a resolved scene reads none, so it runs alike on every node, and a
        checkpoint records the setting that ran. Rollout actors refuse unresolved scenes.

        Raises:
            ValueError: the fidelity does not resolve (one line; loading the scene has
                already checked this on the machine that loaded it).
        """
        if self.is_resolved:
            return self
        found = {
            b: resolve_profile(self.fidelity, b, self.name, self.fidelity_tolerance)
            for b in self.backends
        }
        return self.model_copy(
            update={
                "fidelity": {b: profile for b, (profile, _) in found.items()},
                "fidelity_names": {b: name for b, (_, name) in found.items() if name},
            }
        )


def resolve_profile(
    fidelity: Fidelity, backend: str, scene: str | None = None, tolerance: float | None = None
) -> tuple[FidelityProfile, str | None]:
    """A scene's fidelity field resolved for ``backend``, and the name it came by (None for an
    explicit profile); raises ``ValueError`` (one line) if it does not resolve.

    Besides the built-in names (``NAMED_PROFILES``), a name may be a profile saved by
    ``gaitforge fidelity sweep``, and ``auto`` picks the saved one for ``scene`` within
    ``tolerance`` (rad); both read this machine's profile directory (``saved_profiles``).
    """
    if isinstance(fidelity, dict):
        if backend not in fidelity:
            raise ValueError(f"fidelity: no profile for backend {backend!r}")
        return resolve_profile(fidelity[backend], backend, scene, tolerance)  # type: ignore[index]
    if isinstance(fidelity, FidelityProfile):
        return check_profile(fidelity, backend), None
    named = NAMED_PROFILES[backend]
    if fidelity in named:
        return named[fidelity], fidelity
    if fidelity == "auto":
        saved = saved_profiles.auto(scene, backend, tolerance)
        return saved.profile, f"auto: {saved.name}"
    found = saved_profiles.by_name(fidelity, backend)
    if found is not None:
        return found.profile, fidelity
    raise ValueError(
        f"fidelity: unknown profile {fidelity!r} for backend {backend!r}; "
        f"allowed: {sorted(named)}, a saved profile, auto, or an explicit "
        "{integrator, timestep}"
    )


__all__ = [
    "BACKENDS",
    "Imitate",
    "Keep",
    "Obstacles",
    "RewardWeights",
    "Scene",
    "Task",
    "Terrain",
]
