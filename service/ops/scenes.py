"""Scene operations: the catalogue, a scene's compile report, and random-excitation checks."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

from gaitforge.service.ops.errors import InputError
from gaitforge.workers.scenes import Scene, catalogue, load_option, load_scene, option_names
from gaitforge.workers.scenes.compose import compose
from gaitforge.workers.scenes.profiles import FidelityProfile
from pydantic import BaseModel, Field

if TYPE_CHECKING:
    from gaitforge.workers.probe import ProbeResult
    from gaitforge.workers.sim.base import CompileReport

Backend = Literal["mujoco", "opensim"]
BACKENDS: tuple[Backend, ...] = ("mujoco", "opensim")
SIZE_KEYS = (
    "dofs",
    "joints",
    "bodies",
    "muscles",
    "tendons",
    "wrap_objects",
    "geoms",
    "sites",
    "contact_pairs",
)
"""model size counts of a compile report, in display order"""


class SceneSummary(BaseModel):
    """One catalogue scene, as listed."""

    name: str
    body: str
    backends: list[str]
    task: str = Field(description="the task's kind: reach, locomotion, ...")
    target_speed_m_s: float | None = Field(description="m/s, locomotion tasks")
    control_hz: float = Field(description="Hz: policy actions per simulated second")
    episode_s: float = Field(description="s: simulated length of an episode")
    description: str


class SceneReport(BaseModel):
    """What compiling a scene for a backend kept and dropped, and the model size it saved.

    ``size_full`` is the body with nothing removed, ``size`` the scene's model and ``saved``
    their difference; keys are :data:`SIZE_KEYS`.
    """

    scene: str
    backend: str
    body: str
    profile: FidelityProfile = Field(description="the concrete fidelity profile it runs with")
    mass_kg: float
    size_full: dict[str, int]
    size: dict[str, int]
    saved: dict[str, int]
    kept_dofs: list[str]
    locked_dofs: dict[str, float] = Field(description="dof -> value it is welded at, rad or m")
    dropped_joints: list[str]
    kept_muscles: list[str]
    removed_muscles: dict[str, str] = Field(description="muscle -> why it was removed")
    contact_geoms: list[str]
    obstacles: int
    notes: list[str]

    @classmethod
    def of(cls, report: CompileReport) -> SceneReport:
        plan = report.plan
        return cls(
            scene=report.scene,
            backend=report.backend,
            body=report.body,
            profile=report.profile,
            mass_kg=report.mass,
            size_full=report.size_full,
            size=report.size,
            saved=report.saved(),
            kept_dofs=plan.kept_dofs,
            locked_dofs=plan.locked_dofs,
            dropped_joints=report.dropped_joints,
            kept_muscles=plan.kept_muscles,
            removed_muscles=plan.removed_muscles,
            contact_geoms=plan.contact_geoms,
            obstacles=plan.obstacles,
            notes=plan.notes,
        )


class CheckResult(BaseModel):
    """Random excitations on one scene: speed and what ended the episodes."""

    scene: str
    backend: str
    seconds: float = Field(description="s of wall-clock time asked for")
    steps: int = Field(description="env (control) steps taken")
    wall_s: float = Field(description="s of wall-clock time spent stepping")
    sim_s: float = Field(description="s of simulated time covered")
    steps_per_s: float = Field(description="env steps per wall-clock second")
    realtime_factor: float = Field(description="simulated s per wall-clock s")
    episodes: int = Field(description="episodes ended (terminated or truncated)")
    falls: int = Field(description="episodes ended by a fall")
    health: dict[str, int] = Field(description="simulator failure cause -> episodes it ended")


def check_backend(backend: str) -> Backend:
    """``backend`` if it names a simulator, else :class:`InputError`."""
    if backend not in BACKENDS:
        raise InputError("backend", f"unknown {backend!r}; allowed: {list(BACKENDS)}")
    return backend  # type: ignore[return-value]


def load_for(
    name: str, backend: str | None = None, overrides: dict[str, Any] | None = None
) -> tuple[Scene, Backend]:
    """The scene ``name`` (catalogue ``base+option+...`` or YAML path) with ``overrides``
    (dotted path -> value) and the backend to run it on (default: its first).

    Raises:
        SpecError: an unknown scene, a bad scene file or override (naming the field).
        InputError: a backend the scene does not run on.
    """
    scene = load_scene(name, overrides)
    chosen = check_backend(backend or scene.backends[0])
    if chosen not in scene.backends:
        raise InputError("backend", f"scene {scene.name!r} runs on {scene.backends}")
    return scene.resolved(), chosen  # resolved here, where it is loaded (Scene.resolved)


class OptionSummary(BaseModel):
    """One catalogue option, as listed."""

    name: str
    bases: list[str] = Field(description="the base scenes it composes onto (empty: any)")
    requires: list[str] = Field(description="options that must come before it")
    description: str


def list_options() -> list[OptionSummary]:
    """Every shipped scene option, by name."""
    lineages = {base: compose(base).lineage for base in catalogue()}
    out = []
    for name in option_names():
        option = load_option(name)
        takes = [b for b, lineage in lineages.items() if set(lineage) & set(option.bases)]
        out.append(
            OptionSummary(
                name=option.name,
                bases=takes,
                requires=option.requires,
                description=" ".join(option.description.split()),
            )
        )
    return out


def list_scenes() -> list[SceneSummary]:
    """Every shipped base scene, by name."""
    out = []
    for name in catalogue():
        s = load_scene(name)
        out.append(
            SceneSummary(
                name=s.name,
                body=s.body,
                backends=list(s.backends),
                task=s.task.kind,
                target_speed_m_s=s.task.target_speed,
                control_hz=s.control_hz,
                episode_s=s.episode_s,
                description=" ".join(s.description.split()),
            )
        )
    return out


def show_scene(
    name: str, backend: str | None = None, overrides: dict[str, Any] | None = None
) -> SceneReport:
    """Compile scene ``name`` (with ``overrides``) for ``backend`` (default: its first) and
    report what it kept, what it dropped and what that saved (see :func:`load_for`)."""
    from gaitforge.workers.sim import make_simulator  # lazy: imports MuJoCo

    scene, chosen = load_for(name, backend, overrides)
    return SceneReport.of(make_simulator(scene, chosen).report)


def scenes_to_check(
    name: str | None,
    backend: str,
    all_scenes: bool = False,
    overrides: dict[str, Any] | None = None,
) -> list[Scene]:
    """Scene ``name`` (with ``overrides``), or with ``all_scenes`` every catalogue base scene
    that runs on ``backend``.

    Raises:
        InputError: both or neither of ``name`` and ``all_scenes``; no scene on ``backend``.
        SpecError: see :func:`load_for`.
    """
    if all_scenes == (name is not None):
        raise InputError("name", "give a scene name or all scenes, not both or neither")
    chosen = check_backend(backend)
    if name is not None:
        return [load_for(name, chosen, overrides)[0]]
    scenes = [s.resolved() for s in map(load_scene, catalogue()) if chosen in s.backends]
    if not scenes:
        raise InputError("backend", f"no catalogue scene runs on {chosen!r} yet")
    return scenes


def check_scene(
    scene: Scene,
    backend: str,
    seconds: float,
    seed: int = 0,
    on_step: Callable[[ProbeResult], None] | None = None,
) -> CheckResult:
    """Step ``scene`` with uniform random excitations for ``seconds`` of wall-clock time;
    ``on_step`` sees the running totals after every step."""
    from gaitforge.workers.env import MuscleEnv  # lazy: imports MuJoCo
    from gaitforge.workers.probe import random_excitations

    if not seconds > 0:
        raise InputError("seconds", f"must be > 0, got {seconds:g}")
    env = MuscleEnv(scene, check_backend(backend))
    try:
        r = random_excitations(env, seconds, seed=seed, on_step=on_step)
    finally:
        env.close()
    return CheckResult(
        scene=scene.name,
        backend=backend,
        seconds=seconds,
        steps=r.steps,
        wall_s=r.wall_s,
        sim_s=r.sim_s,
        steps_per_s=r.steps_per_s,
        realtime_factor=r.realtime_factor,
        episodes=r.episodes,
        falls=r.falls,
        health=dict(sorted(r.health.items())),
    )


def check_scenes(
    name: str | None,
    backend: str = "mujoco",
    seconds: float = 5.0,
    seed: int = 0,
    all_scenes: bool = False,
) -> list[CheckResult]:
    """:func:`check_scene` on each of :func:`scenes_to_check`."""
    return [
        check_scene(scene, backend, seconds, seed)
        for scene in scenes_to_check(name, backend, all_scenes)
    ]
