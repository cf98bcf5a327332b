"""``gaitforge scenes ...``: list the catalogue, show a compile report, check a scene."""

from __future__ import annotations

from enum import StrEnum

import typer
from gaitforge.workers.scenes import Scene, catalogue, load_scene
from gaitforge.workers.spec_io import SpecError
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

scenes_app = typer.Typer(help="The scene catalogue.", no_args_is_help=True)
console = Console()


class BackendChoice(StrEnum):
    mujoco = "mujoco"
    opensim = "opensim"


BACKEND_OPTION = typer.Option(BackendChoice.mujoco, help="Simulator backend.")


def _fail(message: str) -> typer.Exit:
    console.print(f"[red]error:[/red] {message}", soft_wrap=True)
    return typer.Exit(2)


def _load(name: str, backend: BackendChoice) -> Scene:
    """The scene, checked to run on ``backend``; exits with one line on any fault."""
    try:
        scene = load_scene(name)
    except SpecError as exc:
        raise _fail(str(exc)) from None
    if backend.value not in scene.backends:
        raise _fail(f"--backend: scene {scene.name!r} runs on {scene.backends}")
    return scene


@scenes_app.command("list")
def list_scenes() -> None:
    """The shipped scenes."""
    table = Table("scene", "body", "backends", "task", "control Hz", "episode s", "description")
    for name in catalogue():
        s = load_scene(name)
        task = s.task.kind + (f" {s.task.target_speed} m/s" if s.task.target_speed else "")
        table.add_row(
            s.name, s.body, ",".join(s.backends), task, f"{s.control_hz:g}", f"{s.episode_s:g}",
            " ".join(s.description.split()),
        )  # fmt: skip
    console.print(table)


@scenes_app.command("show")
def show(
    name: str = typer.Argument(help="Catalogue name or path to a scene YAML."),
    backend: BackendChoice = BACKEND_OPTION,
) -> None:
    """Compile a scene and print what it kept, what it dropped and what that saved."""
    from gaitforge.service.report_view import render_report  # lazy: imports MuJoCo
    from gaitforge.workers.sim import make_simulator  # lazy: imports MuJoCo

    scene = _load(name, backend)
    console.print(render_report(make_simulator(scene, backend.value).report))


@scenes_app.command("check")
def check(
    name: str = typer.Argument(None, help="Catalogue name or scene YAML; omit with --all."),
    seconds: float = typer.Option(5.0, min=0.1, help="Wall-clock seconds per scene."),
    backend: BackendChoice = BACKEND_OPTION,
    all_scenes: bool = typer.Option(False, "--all", help="Every catalogue scene on --backend."),
    seed: int = typer.Option(0, help="Seed of the random excitations."),
) -> None:
    """Step with random excitations: env steps/s, real-time factor and health counts."""
    from gaitforge.workers.env import MuscleEnv  # lazy: imports MuJoCo
    from gaitforge.workers.probe import random_excitations  # lazy: imports MuJoCo

    if all_scenes == (name is not None):
        raise _fail("give a scene NAME or --all, not both or neither")
    if all_scenes:
        scenes = [s for s in map(load_scene, catalogue()) if backend.value in s.backends]
    else:
        scenes = [_load(name, backend)]
    if not scenes:
        raise _fail(f"--backend: no catalogue scene runs on {backend.value!r} yet")
    table = Table("scene", "backend", "steps", "steps/s", "real-time x", "episodes", "falls",
                  "health failures")  # fmt: skip
    for scene in scenes:
        env = MuscleEnv(scene, backend.value)
        with Progress(
            TextColumn(f"{scene.name} [{backend.value}]"), BarColumn(),
            TextColumn("{task.fields[rate]}"), TimeElapsedColumn(),
            console=console, transient=True, disable=not console.is_terminal,
        ) as progress:  # fmt: skip
            task = progress.add_task("check", total=seconds, rate="")

            def update(r, task=task, progress=progress) -> None:
                progress.update(task, completed=r.wall_s, rate=f"{r.steps_per_s:.0f} steps/s")

            result = random_excitations(env, seconds, seed=seed, on_step=update)
        failures = ", ".join(f"{k}: {v}" for k, v in sorted(result.health.items())) or "none"
        table.add_row(
            scene.name, backend.value, str(result.steps), f"{result.steps_per_s:.0f}",
            f"{result.realtime_factor:.2f}", str(result.episodes), str(result.falls), failures,
        )  # fmt: skip
    console.print(table)
