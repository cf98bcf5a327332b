"""``gaitforge evaluate CKPT``: a checkpoint's distance, speed, falls, effort and health over
seeded episodes, and the speed-against-safety sweep (the work is
:mod:`gaitforge.service.ops.evaluate`'s; this parses and prints)."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from gaitforge.service.cli_options import AsJson, SetFields, assignments
from gaitforge.service.console import err, fail, out, print_json
from gaitforge.service.evaluate_view import render, render_episodes
from gaitforge.service.ops import InputError, validate_request
from gaitforge.service.ops import evaluate as ops
from gaitforge.workers.spec_types import SEED_LIMIT
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


class ModeChoice(StrEnum):
    deterministic = "deterministic"
    stochastic = "stochastic"
    both = "both"


class PickChoice(StrEnum):
    latest = "latest"
    best = "best"


class BackendChoice(StrEnum):
    mujoco = "mujoco"
    opensim = "opensim"


def evaluate(
    checkpoint: Annotated[Path, typer.Argument(help="Checkpoint directory, or a run directory.")],
    scene: Annotated[
        str | None, typer.Option(help="Evaluate on this scene (name or YAML) instead.")
    ] = None,
    backend: Annotated[
        BackendChoice | None, typer.Option(help="Simulator; default the checkpoint's.")
    ] = None,
    episodes: Annotated[int, typer.Option(help="Episodes per mode and per sweep point.")] = 10,
    mode: Annotated[ModeChoice, typer.Option(help="Action mode(s).")] = ModeChoice.deterministic,
    seed: Annotated[
        int, typer.Option(min=0, max=SEED_LIMIT - 1, help="Episode i resets with seed + i.")
    ] = 0,
    set_fields: SetFields = None,
    sweep: Annotated[bool, typer.Option("--sweep", help="Speed-against-safety sweep.")] = False,
    sweep_percent: Annotated[
        str, typer.Option(help="Target speed reductions for --sweep, in percent.")
    ] = "0,10,20,30",
    pick: Annotated[
        PickChoice, typer.Option(help="From a run directory: the latest or the best (return).")
    ] = PickChoice.latest,
    record: Annotated[
        Path | None, typer.Option(help="MCAP recording of the first episode.")
    ] = None,
    video: Annotated[Path | None, typer.Option(help="MP4 video of the first episode.")] = None,
    gait: Annotated[
        Path | None,
        typer.Option(help="PNG of the first episode's gait cycle beside the recorded gait."),
    ] = None,
    per_episode: Annotated[
        bool, typer.Option("--per-episode", help="Also a table of every episode.")
    ] = False,
    json_stdout: AsJson = False,
    json_out: Annotated[
        Path | None, typer.Option("--json-out", help="Also write the results as JSON here.")
    ] = None,
) -> None:
    """Evaluate a checkpoint: distance, speed, fall rate, effort, return and health."""
    modes = ["deterministic", "stochastic"] if mode is ModeChoice.both else [mode.value]
    try:
        reductions = ops.parse_percentages(sweep_percent) if sweep else None
        request = validate_request(
            ops.EvaluateRequest,
            checkpoint=checkpoint,
            scene=scene,
            backend=backend.value if backend else None,
            episodes=episodes,
            modes=modes,
            seed=seed,
            sweep=reductions,
            pick=pick.value,
            record=record,
            video=video,
            gait=gait,
            scene_set=assignments(set_fields),
        )
    except InputError as exc:
        raise fail(exc) from None
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err,
        transient=True,
        disable=not err.is_terminal,
    ) as progress:
        tasks: dict[str, Any] = {}

        def on_episode(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = progress.add_task(label, total=total)
            progress.update(tasks[label], completed=done)

        try:
            report = ops.evaluate(request, progress=on_episode)
        except ops.user_errors() as exc:
            raise fail(exc) from None
    if json_out is not None:
        ops.write_report(report, json_out)
    if json_stdout:
        print_json(ops.report_json(report))
        return
    if per_episode:
        for episodes_table in render_episodes(report):
            out.print(episodes_table)
    out.print(render(report, out))
    if json_out is not None:
        out.print(f"results written to {json_out}")
