"""``gaitforge fidelity ...``: measure speed against accuracy for a scene (``sweep``) and
numerical stability at the extremes (``stress``)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import typer
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

fidelity_app = typer.Typer(
    help="Speed for accuracy: fidelity sweeps and stress.", no_args_is_help=True
)
console = Console()
logger = logging.getLogger(__name__)
OUT_OPTION = typer.Option(Path("fidelity-results"), help="Directory for CSV, JSON, PNG.")


def _fail(message: str) -> typer.Exit:
    console.print(f"[red]error:[/red] {message}", soft_wrap=True)
    return typer.Exit(2)


def _load(name: str, backend: str | None) -> tuple[Scene, str]:
    try:
        scene = load_scene(name)
    except SpecError as exc:
        raise _fail(str(exc)) from None
    backend = backend or scene.backends[0]
    if backend not in scene.backends:
        raise _fail(f"--backend: scene {scene.name!r} runs on {scene.backends}")
    return scene, backend


def _progress(total: int) -> Progress:
    return Progress(
        TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
        TextColumn("{task.fields[last]}"), TimeElapsedColumn(),
        console=console, transient=True, disable=not console.is_terminal,
    )  # fmt: skip


def _num(x: float, fmt: str = ".3g") -> str:
    return "inf" if x == float("inf") else format(x, fmt)


@fidelity_app.command("sweep")
def sweep(
    scene_name: str = typer.Argument(..., metavar="SCENE", help="Catalogue name or scene YAML."),
    backend: str = typer.Option(None, help="mujoco or opensim (default: the scene's first)."),
    tolerance: float = typer.Option(0.01, help="rad: allowed RMS joint-angle error."),
    quick: bool = typer.Option(False, "--quick", help="A small grid and short runs (tests)."),
    out: Path = OUT_OPTION,
    integrators: str = typer.Option(
        None, help="Comma-separated integrators to keep from the grid (default: all)."
    ),
    no_model: bool = typer.Option(False, "--no-model", help="Skip the model-error checks."),
    save: bool = typer.Option(True, help="Save the recommendation as a named profile."),
    task_tolerance: float = typer.Option(
        None, help="m: also require the mean distance covered within this of the reference's."
    ),
) -> None:
    """Measure every profile of the grid; write CSV, JSON and a Pareto plot; recommend and
    save the fastest profile within tolerance."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from gaitforge.workers.fidelity.grid import SweepSize, sweep_grid
    from gaitforge.workers.fidelity.report import write_all
    from gaitforge.workers.fidelity.sweep import run_sweep, save_recommendation

    if tolerance <= 0:
        raise _fail(f"--tolerance: must be > 0 rad, got {tolerance:g}")
    if task_tolerance is not None and task_tolerance < 0:
        raise _fail(f"--task-tolerance: must be >= 0 m, got {task_tolerance:g}")
    scene, backend = _load(scene_name, backend)
    grid = sweep_grid(scene, backend, quick)
    if integrators is not None:
        keep = {i.strip() for i in integrators.split(",") if i.strip()}
        grid = [p for p in grid if p.integrator in keep]
    if not grid:
        raise _fail(f"grid: no profile left to sweep for {scene.name!r} on {backend} "
                    f"(--integrators {integrators!r})")  # fmt: skip
    size = SweepSize.for_run(backend, quick)
    model_checks = not no_model and not quick
    with _progress(len(grid) + 2) as progress:
        task = progress.add_task(
            f"{scene.name} [{backend}]", total=len(grid) + 2 + 3 * model_checks, last=""
        )

        def advance(text: str) -> None:
            progress.update(task, advance=1, last=text)

        try:
            result = run_sweep(
                scene, backend, tolerance, grid, size, advance, model_checks, task_tolerance
            )
        except SpecError as exc:
            raise _fail(str(exc)) from None
    paths = write_all(result, out)
    ref = result.reference
    console.print(
        f"reference {ref['profile']}: refined ({ref['refined']}) changes it by "
        f"{ref['refined_change']:.3g} rad RMS; margin {ref['margin']:.1f}x the tolerance "
        f"{tolerance:g} rad (needs {ref['required_margin']:g}x): "
        + ("[green]converged[/green]" if ref["converged"] else "[red]NOT converged[/red]")
    )
    columns = ["profile", "steps/s", "real-time x", f"err {size.short:g}s", f"err {size.long:g}s"]
    table = Table(*columns, "distance vs ref (m)", "falls", "stable", "within")
    for r in sorted(result.rows, key=lambda r: -r.steps_per_s):
        t = r.task
        table.add_row(
            r.label, f"{r.steps_per_s:.0f}", f"{r.realtime:.2f}", _num(r.err_short),
            _num(r.err_long), f"{t['distance_vs_ref']:+.3f} ± {t['distance_vs_ref_ci']:.3f}",
            f"{t['fall_rate']:.2f}", "yes" if r.stable else f"[red]{r.health}[/red]",
            "[green]yes[/green]" if r.within else "no",
        )  # fmt: skip
    console.print(table)
    if result.model:
        mt = Table("model difference", "setting", f"rms {size.short:g}s", f"rms {size.long:g}s",
                   "speed ratio", "note")  # fmt: skip
        for m in result.model:
            mt.add_row(m["what"], m["setting"], _num(m["rms_short"]), _num(m["rms_long"]),
                       f"{m['speed_ratio']:.2f}", m["note"])  # fmt: skip
        console.print(mt)
    best = result.recommended
    if best is None:
        console.print(f"[yellow]no stable profile within {tolerance:g} rad[/yellow]")
    else:
        line = (
            f"recommended: {best.label} ({best.steps_per_s:.0f} steps/s, "
            f"error {best.error:.3g} rad)"
        )
        if save and (written := save_recommendation(result)) is not None:
            saved, path = written
            line += f"; saved as {saved.name!r} ({path})"
        console.print(line, soft_wrap=True)
    if result.challenge is not None:
        c = result.challenge
        console.print(
            f"against the 2017 challenge's {c['challenge']} ({c['challenge_steps_per_s']:.0f} "
            f"steps/s, error {c['challenge_error']:.3g} rad): {c['speedup']:.1f}x faster"
        )
    console.print(f"wrote {', '.join(str(p) for p in paths.values())}", soft_wrap=True)


@fidelity_app.command("stress")
def stress(
    scene_name: str = typer.Argument(..., metavar="SCENE", help="Catalogue name or scene YAML."),
    backend: str = typer.Option(None, help="mujoco or opensim (default: the scene's first)."),
    seconds: float = typer.Option(1.0, min=0.01, help="Simulated s per scenario."),
    quick: bool = typer.Option(False, "--quick", help="Fewer profiles, scenarios and checks."),
    bisect: bool = typer.Option(True, help="Bisect for the largest stable step/accuracy."),
) -> None:
    """Every profile under hostile inputs (all 0, all 1, bang-bang, random, spinning joints,
    a 0.5 m drop), a stability map, and by bisection the largest stable timestep (MuJoCo)
    or loosest stable accuracy (OpenSim) per integrator."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from gaitforge.workers.fidelity.grid import stress_grid
    from gaitforge.workers.fidelity.stress import SCENARIOS, bisect_limits, stability_map

    scene, backend = _load(scene_name, backend)
    profiles = stress_grid(scene, backend, quick)
    scenarios = ("ones", "random") if quick else SCENARIOS
    with _progress(len(profiles) * len(scenarios)) as progress:
        task = progress.add_task(f"stress {scene.name} [{backend}]",
                                 total=len(profiles) * len(scenarios), last="")  # fmt: skip
        rows = stability_map(scene, backend, profiles, seconds, scenarios,
                             lambda t: progress.update(task, advance=1, last=t))  # fmt: skip
    table = Table("profile", *scenarios, title=f"stability map: {scene.name} on {backend}")
    for row in rows:
        table.add_row(row["profile"], *(
            "[green]ok[/green]" if row[s] == "ok" else f"[red]{row[s]}[/red]" for s in scenarios
        ))  # fmt: skip
    console.print(table)
    if not bisect:
        return
    integrators = (profiles[0].integrator,) if quick else None
    with _progress(0) as progress:
        task = progress.add_task("bisection", total=None, last="")
        limits = bisect_limits(scene, backend, seconds, integrators, scenarios,
                               lambda t: progress.update(task, advance=1, last=t))  # fmt: skip
    if backend == "mujoco":
        heads, scale = ("largest stable step (ms)", "smallest unstable step (ms)"), 1e3
    else:
        heads, scale = ("loosest stable accuracy", "tightest unstable accuracy"), 1.0
    lt = Table("integrator", *heads, "checks")
    for lim in limits:
        lt.add_row(
            lim.integrator,
            "none" if lim.largest_stable is None else f"{lim.largest_stable * scale:.3g}",
            "none" if lim.smallest_unstable is None else f"{lim.smallest_unstable * scale:.3g}",
            str(lim.checks),
        )
    console.print(lt)
