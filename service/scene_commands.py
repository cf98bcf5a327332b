"""``gaitforge scenes ...``: list the catalogue, show a compile report, check a scene."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from workers.scenes import catalogue, load_scene
from workers.spec_io import SpecError

scenes_app = typer.Typer(help="The scene catalogue.", no_args_is_help=True)
console = Console()


def _load(name: str):
    try:
        return load_scene(name)
    except SpecError as exc:
        console.print(f"[red]error:[/red] {exc}", soft_wrap=True)
        raise typer.Exit(2) from None


@scenes_app.command("list")
def list_scenes() -> None:
    """The shipped scenes."""
    table = Table("scene", "body", "backends", "task", "control Hz", "episode s", "description")
    for name in catalogue():
        s = load_scene(name)
        task = s.task.kind + (f" {s.task.target_speed} m/s" if s.task.target_speed else "")
        table.add_row(
            s.name, s.body, ",".join(s.backends), task, f"{s.control_hz:g}", f"{s.episode_s:g}",
            " ".join(s.description.split())[:60],
        )  # fmt: skip
    console.print(table)


@scenes_app.command("show")
def show(
    name: str = typer.Argument(help="Catalogue name or path to a scene YAML."),
    backend: str = typer.Option("mujoco", help="Simulator backend."),
) -> None:
    """Compile a scene and print what it kept, what it dropped and what that saved."""
    from service.report_view import render_report
    from workers.sim import make_simulator

    scene = _load(name)
    _check_backend(scene, backend)
    console.print(render_report(make_simulator(scene, backend).report))


@scenes_app.command("check")
def check(
    name: str = typer.Argument(None, help="Catalogue name or scene YAML; omit with --all."),
    seconds: float = typer.Option(5.0, min=0.1, help="Wall-clock seconds per scene."),
    backend: str = typer.Option("mujoco", help="Simulator backend."),
    all_scenes: bool = typer.Option(False, "--all", help="Check every catalogue scene."),
    seed: int = typer.Option(0, help="Seed of the random excitations."),
) -> None:
    """Step with random excitations: env steps/s, real-time factor and health counts."""
    from workers.env import MuscleEnv
    from workers.probe import random_excitations

    if all_scenes == (name is not None):
        console.print("[red]error:[/red] give a scene NAME or --all, not both or neither")
        raise typer.Exit(2)
    names = catalogue() if all_scenes else [name]
    table = Table(
        "scene",
        "backend",
        "steps",
        "steps/s",
        "real-time x",
        "episodes",
        "falls",
        "health failures",
    )
    for scene_name in names:
        scene = _load(scene_name)
        if backend not in scene.backends:
            continue
        env = MuscleEnv(scene, backend)
        with Progress(
            TextColumn(f"{scene.name} [{backend}]"),
            BarColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeElapsedColumn(),
            console=console,
            transient=True,
        ) as progress:
            task = progress.add_task("check", total=seconds, rate="")

            def update(r, task=task, progress=progress) -> None:
                progress.update(task, completed=r.wall_s, rate=f"{r.steps_per_s:.0f} steps/s")

            result = random_excitations(env, seconds, seed=seed, on_step=update)
        failures = ", ".join(f"{k}: {v}" for k, v in sorted(result.health.items())) or "none"
        table.add_row(
            scene.name,
            backend,
            str(result.steps),
            f"{result.steps_per_s:.0f}",
            f"{result.realtime_factor:.2f}",
            str(result.episodes),
            str(result.falls),
            failures,
        )
    console.print(table)


def _check_backend(scene, backend: str) -> None:
    if backend not in scene.backends:
        console.print(f"[red]error:[/red] --backend: scene {scene.name!r} runs on {scene.backends}")
        raise typer.Exit(2)
