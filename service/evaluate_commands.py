"""``gaitforge evaluate CKPT``: a checkpoint's distance, speed, falls, effort and health over
seeded episodes, and the speed-against-safety sweep (see ``learner.evaluate``)."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console, Group
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

console = Console()


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


def _fail(message: str) -> typer.Exit:
    console.print(f"[red]error:[/red] {escape(message)}", soft_wrap=True, highlight=False)
    return typer.Exit(2)


def _parse_reductions(text: str) -> list[float]:
    """ "0,10,20,30" (percent) -> [0.0, 0.1, 0.2, 0.3]."""
    try:
        values = [float(part) / 100.0 for part in text.split(",") if part.strip()]
    except ValueError:
        raise _fail(f"--sweep-percent {text!r}: expected comma-separated percentages") from None
    if not values or any(not 0.0 <= v < 1.0 for v in values):
        raise _fail(f"--sweep-percent {text!r}: each must be in [0, 100)")
    return values


def _ci(stat: Any, fmt: str = ".2f") -> str:
    if stat.n == 0:
        return "-"
    if stat.n == 1:
        return f"{stat.mean:{fmt}}"
    return f"{stat.mean:{fmt}} ± {(stat.high - stat.low) / 2:{fmt}}"


def _rate(rate: Any) -> str:
    return f"{100 * rate.value:.0f} % ({100 * rate.low:.0f}-{100 * rate.high:.0f})"


def _health(counts: dict[str, int]) -> str:
    failures = {k: v for k, v in counts.items() if k != "ok"}
    return ", ".join(f"{k}: {v}" for k, v in failures.items()) or "none"


def render_episodes(report: Any) -> list[Table]:
    """One table per mode: every episode of an ``EvaluationReport``."""
    tables = []
    for mode, r in report.results.items():
        table = Table(
            "seed", "steps", "time s", "distance m", "speed m/s", "fell", "health", "effort",
            "return", title=f"Episodes ({mode})",
        )  # fmt: skip
        for e in r.episodes:
            table.add_row(
                str(e.seed), str(e.steps), f"{e.time_s:.2f}", f"{e.distance_m:.2f}",
                f"{e.mean_speed_m_s:.2f}", "yes" if e.fell else "no", e.health,
                f"{e.effort:.3f}", f"{e.return_:.1f}",
            )  # fmt: skip
        tables.append(table)
    return tables


def render(report: Any) -> Group:
    """Rich tables of an ``EvaluationReport`` (means ± the half-width of their 95 % interval;
    rates with their 95 % Wilson interval)."""
    head = (
        f"[bold]{report.checkpoint}[/bold]: {report.env_steps} env steps; scene "
        f"{report.scene} on {report.backend}; seeds {report.seed}.."
    )
    first = next(iter(report.results.values()))
    head += f"{report.seed + len(first.episodes) - 1}; means ± 95 % intervals"
    table = Table(
        "mode", "target m/s", "distance m", "speed m/s", "fall rate", "time s", "effort",
        "return", "health failures", title="Evaluation",
    )  # fmt: skip
    for mode, r in report.results.items():
        target = "-" if r.target_speed_m_s is None else f"{r.target_speed_m_s:.2f}"
        table.add_row(
            mode, target, _ci(r.distance_m), _ci(r.mean_speed_m_s), _rate(r.fall_rate),
            _ci(r.time_s), _ci(r.effort, ".3f"), _ci(r.return_, ".1f"), _health(r.health),
        )  # fmt: skip
    parts: list[Any] = [head, table]
    if report.sweep:
        sweep = Table(
            "slower by", "target m/s", "fall rate", "distance m", "speed m/s", "return",
            "health failures", title=f"Speed against safety ({report.sweep_mode})",
        )  # fmt: skip
        for point in report.sweep:
            r = point.result
            sweep.add_row(
                f"{100 * point.reduction:.0f} %", f"{point.target_speed_m_s:.2f}",
                _rate(r.fall_rate), _ci(r.distance_m), _ci(r.mean_speed_m_s),
                _ci(r.return_, ".1f"), _health(r.health),
            )  # fmt: skip
        parts.append(sweep)
    return Group(*parts)


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
    seed: Annotated[int, typer.Option(help="Episode i resets with seed + i.")] = 0,
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
    per_episode: Annotated[
        bool, typer.Option("--per-episode", help="Also a table of every episode.")
    ] = False,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the results as JSON here.")
    ] = None,
) -> None:
    """Evaluate a checkpoint: distance, speed, fall rate, effort, return and health."""
    from gaitforge.learner.checkpoint import CheckpointError  # lazy: imports torch
    from gaitforge.learner.evaluate import EvaluationError, evaluate_checkpoint, write_json

    if episodes <= 0:
        raise _fail(f"--episodes must be > 0, got {episodes}")
    if not checkpoint.exists():
        raise _fail(f"{checkpoint}: no such file or directory")
    reductions = _parse_reductions(sweep_percent) if sweep else None
    modes = ["deterministic", "stochastic"] if mode is ModeChoice.both else [mode.value]
    with Progress(
        TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(), console=console, transient=True, disable=not console.is_terminal,
    ) as progress:  # fmt: skip
        tasks: dict[str, Any] = {}

        def on_episode(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = progress.add_task(label, total=total)
            progress.update(tasks[label], completed=done)

        try:
            report = evaluate_checkpoint(
                checkpoint, scene=scene, backend=backend.value if backend else None,
                episodes=episodes, modes=modes, seed=seed, sweep=reductions,
                sweep_mode=modes[0], record=record, video=video, pick=pick.value,
                progress=on_episode,
            )  # fmt: skip
        except (EvaluationError, CheckpointError) as exc:
            raise _fail(str(exc)) from None
    if per_episode:
        for table in render_episodes(report):
            console.print(table)
    console.print(render(report))
    if json_out is not None:
        write_json(report, json_out)
        console.print(f"results written to {json_out}")
