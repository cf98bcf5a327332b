"""``gaitforge scenes ...``: list the catalogue, show a compile report, check a scene (the
work is :mod:`gaitforge.service.ops.scenes`'s; this parses and prints)."""

from __future__ import annotations

from enum import StrEnum

import typer
from gaitforge.service.cli_options import AsJson, SetFields, assignments
from gaitforge.service.console import err, fail, out, print_json, table
from gaitforge.service.ops import SpecError
from gaitforge.service.ops import scenes as ops
from gaitforge.workers.spec_types import SEED_LIMIT
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

scenes_app = typer.Typer(help="The scene catalogue.", no_args_is_help=True)
WIDE = 120
"""columns from which ``scenes list`` shows descriptions in the table (else below it)"""
MAX_CHECK_S = 3600.0
"""the longest ``scenes check`` per scene, wall-clock seconds"""


class BackendChoice(StrEnum):
    mujoco = "mujoco"
    opensim = "opensim"


BACKEND_OPTION = typer.Option(BackendChoice.mujoco, help="Simulator backend.")


@scenes_app.command("list")
def list_scenes(json: AsJson = False) -> None:
    """The base scenes and the options that compose onto them (base+option+...)."""
    scenes, options = ops.list_scenes(), ops.list_options()
    if json:
        print_json({"scenes": scenes, "options": options})
        return
    wide = out.width >= WIDE
    headers = ["scene", "body", "backends", "task", "control Hz", "episode s"]
    listing = table(*headers, *(["description"] if wide else []), title="Base scenes")
    for s in scenes:
        speed = f" {s.target_speed_m_s} m/s" if s.target_speed_m_s else ""
        row = [
            s.name,
            s.body,
            ", ".join(s.backends),
            s.task + speed,
            f"{s.control_hz:g}",
            f"{s.episode_s:g}",
        ]
        listing.add_row(*row, *([s.description] if wide else []))
    out.print(listing)
    if not wide:
        for s in scenes:
            out.print(f"[bold]{s.name}[/bold]: {s.description}", highlight=False)
    title = "Options (compose as base+option+..., e.g. run-2d+clock+one-leg)"
    composing = table("option", "for", "after", *(["description"] if wide else []), title=title)
    for o in options:
        row = [o.name, ", ".join(o.bases) or "any", ", ".join(o.requires) or "-"]
        composing.add_row(*row, *([o.description] if wide else []))
    out.print(composing)
    if not wide:
        for o in options:
            out.print(f"[bold]{o.name}[/bold]: {o.description}", highlight=False)


@scenes_app.command("show")
def show(
    name: str = typer.Argument(help="Catalogue scene (base+option+...) or a scene YAML."),
    backend: BackendChoice = BACKEND_OPTION,
    set_fields: SetFields = None,
    json: AsJson = False,
) -> None:
    """Compile a scene and print what it kept, what it dropped and what that saved."""
    from gaitforge.service.report_view import render_report

    try:
        report = ops.show_scene(name, backend.value, assignments(set_fields))
    except SpecError as exc:
        raise fail(exc) from None
    if json:
        print_json(report)
    else:
        out.print(render_report(report))


@scenes_app.command("check")
def check(
    name: str = typer.Argument(
        None, help="Catalogue scene (base+option+...) or scene YAML; omit with --all."
    ),
    seconds: float = typer.Option(
        5.0, min=0.1, max=MAX_CHECK_S, help="Wall-clock seconds per scene."
    ),
    backend: BackendChoice = BACKEND_OPTION,
    all_scenes: bool = typer.Option(False, "--all", help="Every catalogue scene on --backend."),
    seed: int = typer.Option(0, min=0, max=SEED_LIMIT - 1, help="Seed of the random excitations."),
    set_fields: SetFields = None,
    json: AsJson = False,
) -> None:
    """Step with random excitations: env steps/s, real-time factor and health counts."""
    if all_scenes == (name is not None):
        raise fail("give a scene NAME or --all, not both or neither")
    try:
        scenes = ops.scenes_to_check(name, backend.value, all_scenes, assignments(set_fields))
    except SpecError as exc:
        raise fail(exc) from None
    results = []
    for scene in scenes:
        with Progress(
            TextColumn(f"{scene.name} [{backend.value}]"),
            BarColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeElapsedColumn(),
            console=err,
            transient=True,
            disable=not err.is_terminal,
        ) as progress:
            task = progress.add_task("check", total=seconds, rate="")

            def update(r, task=task, progress=progress) -> None:
                progress.update(task, completed=r.wall_s, rate=f"{r.steps_per_s:.0f} steps/s")

            results.append(ops.check_scene(scene, backend.value, seconds, seed, update))
    if json:
        print_json(results)
        return
    title = f"random excitations on {backend.value}, {seconds:g} s per scene"
    listing = table(
        "scene",
        "steps",
        "steps/s",
        "real time x",
        "episodes",
        "falls",
        "health failures",
        title=title,
    )
    for r in results:
        failures = ", ".join(f"{k}: {v}" for k, v in r.health.items()) or "none"
        listing.add_row(
            r.scene,
            str(r.steps),
            f"{r.steps_per_s:.0f}",
            f"{r.realtime_factor:.2f}",
            str(r.episodes),
            str(r.falls),
            failures,
        )
    out.print(listing)
