"""``gaitforge fidelity ...``: measure speed against accuracy for a scene (``sweep``) and
numerical stability at the extremes (``stress``). The work is
:mod:`gaitforge.service.ops.fidelity`'s; this parses and prints."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import typer
from gaitforge.service.cli_options import AsJson
from gaitforge.service.console import err, fail, out, print_json, table
from gaitforge.service.ops import SpecError, validate_request
from gaitforge.service.ops import fidelity as ops
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

fidelity_app = typer.Typer(
    help="Speed for accuracy: fidelity sweeps and stress.", no_args_is_help=True
)
OUT_OPTION = typer.Option(Path("fidelity-results"), "--out", help="Directory for CSV, JSON, PNG.")
MAX_STRESS_S = 600.0
"""the longest ``fidelity stress`` scenario, simulated seconds"""


@contextmanager
def _progress() -> Iterator[ops.ProgressFn]:
    """A progress bar per label on stderr (a terminal only), fed as an ops ``ProgressFn``."""
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[last]}"),
        TimeElapsedColumn(),
        console=err,
        transient=True,
        disable=not err.is_terminal,
    ) as progress:
        tasks: dict[str, object] = {}

        def update(label: str, last: str, done: int, total: int | None) -> None:
            if label not in tasks:
                tasks[label] = progress.add_task(label, total=total, last="")
            progress.update(tasks[label], completed=done, last=last)  # type: ignore[arg-type]

        yield update


def _num(x: float, fmt: str = ".3g") -> str:
    return "inf" if x == float("inf") else format(x, fmt)


@fidelity_app.command("sweep")
def sweep(
    scene_name: str = typer.Argument(..., metavar="SCENE", help="Catalogue name or scene YAML."),
    backend: str = typer.Option(None, help="mujoco or opensim (default: the scene's first)."),
    tolerance: float = typer.Option(0.01, help="rad: allowed RMS joint-angle error."),
    quick: bool = typer.Option(False, "--quick", help="A small grid and short runs (tests)."),
    out_dir: Path = OUT_OPTION,
    integrators: str = typer.Option(
        None, help="Comma-separated integrators to keep from the grid (default: all)."
    ),
    no_model: bool = typer.Option(False, "--no-model", help="Skip the model-error checks."),
    save: bool = typer.Option(True, help="Save the recommendation as a named profile."),
    task_tolerance: float = typer.Option(
        None, help="m: also require the mean distance covered within this of the reference's."
    ),
    json_out: AsJson = False,
) -> None:
    """Measure every profile of the grid; write CSV, JSON and a Pareto plot; recommend and
    save the fastest profile within tolerance."""
    keep = None if integrators is None else [i.strip() for i in integrators.split(",")]
    try:
        request = validate_request(
            ops.SweepRequest,
            scene=scene_name,
            backend=backend,
            tolerance=tolerance,
            quick=quick,
            integrators=[i for i in keep if i] if keep is not None else None,
            model_checks=not no_model,
            task_tolerance=task_tolerance,
            save=save,
            out=out_dir,
        )
        with _progress() as progress:
            outcome = ops.sweep(request, progress)
    except SpecError as exc:
        raise fail(exc) from None
    if json_out:
        print_json(outcome.to_dict())
        return
    result = outcome.result
    ref, size = result.reference, result.size
    out.print(
        f"reference {ref['profile']}: refined ({ref['refined']}) changes it by "
        f"{ref['refined_change']:.3g} rad RMS; margin {ref['margin']:.1f}x the tolerance "
        f"{tolerance:g} rad (needs {ref['required_margin']:g}x): "
        + ("[green]converged[/green]" if ref["converged"] else "[red]NOT converged[/red]")
    )
    columns = ["profile", "steps/s", "real-time x", f"err {size.short:g}s", f"err {size.long:g}s"]
    rows = table(*columns, "distance vs ref (m)", "falls", "stable", "within")
    for r in sorted(result.rows, key=lambda r: -r.steps_per_s):
        t = r.task
        rows.add_row(
            r.label,
            f"{r.steps_per_s:.0f}",
            f"{r.realtime:.2f}",
            _num(r.err_short),
            _num(r.err_long),
            f"{t['distance_vs_ref']:+.3f} ± {t['distance_vs_ref_ci']:.3f}",
            f"{t['fall_rate']:.2f}",
            "yes" if r.stable else f"[red]{r.health}[/red]",
            "[green]yes[/green]" if r.within else "no",
        )
    out.print(rows)
    if result.model:
        mt = table(
            "model difference",
            "setting",
            f"rms {size.short:g}s",
            f"rms {size.long:g}s",
            "speed ratio",
            "note",
        )
        for m in result.model:
            mt.add_row(
                m["what"],
                m["setting"],
                _num(m["rms_short"]),
                _num(m["rms_long"]),
                f"{m['speed_ratio']:.2f}",
                m["note"],
            )
        out.print(mt)
    best = result.recommended
    if best is None:
        out.print(f"[yellow]no stable profile within {tolerance:g} rad[/yellow]")
    else:
        line = (
            f"recommended: {best.label} ({best.steps_per_s:.0f} steps/s, "
            f"error {best.error:.3g} rad)"
        )
        if outcome.saved is not None:
            line += f"; saved as {outcome.saved.name!r} ({outcome.saved_path})"
        out.print(line, soft_wrap=True)
    if result.challenge is not None:
        c = result.challenge
        out.print(
            f"against the 2017 challenge's {c['challenge']} ({c['challenge_steps_per_s']:.0f} "
            f"steps/s, error {c['challenge_error']:.3g} rad): {c['speedup']:.1f}x faster"
        )
    out.print(f"wrote {', '.join(str(p) for p in outcome.files.values())}", soft_wrap=True)


@fidelity_app.command("stress")
def stress(
    scene_name: str = typer.Argument(..., metavar="SCENE", help="Catalogue name or scene YAML."),
    backend: str = typer.Option(None, help="mujoco or opensim (default: the scene's first)."),
    seconds: float = typer.Option(
        1.0, min=0.01, max=MAX_STRESS_S, help="Simulated s per scenario."
    ),
    quick: bool = typer.Option(False, "--quick", help="Fewer profiles, scenarios and checks."),
    bisect: bool = typer.Option(True, help="Bisect for the largest stable step/accuracy."),
    json_out: AsJson = False,
) -> None:
    """Every profile under hostile inputs (all 0, all 1, bang-bang, random, spinning joints,
    a 0.5 m drop), a stability map, and by bisection the largest stable timestep (MuJoCo)
    or loosest stable accuracy (OpenSim) per integrator."""
    try:
        request = validate_request(
            ops.StressRequest,
            scene=scene_name,
            backend=backend,
            seconds=seconds,
            quick=quick,
            bisect=bisect,
        )
        with _progress() as progress:
            outcome = ops.stress(request, progress)
    except SpecError as exc:
        raise fail(exc) from None
    if json_out:
        print_json(outcome.to_dict())
        return
    scenarios = outcome.scenarios
    stability = table(
        "profile", *scenarios, title=f"stability map: {outcome.scene} on {outcome.backend}"
    )
    for row in outcome.rows:
        stability.add_row(
            row["profile"],
            *("[green]ok[/green]" if row[s] == "ok" else f"[red]{row[s]}[/red]" for s in scenarios),
        )
    out.print(stability)
    if not bisect:
        return
    if outcome.limit_kind == "timestep_s":
        heads, scale = ("largest stable step (ms)", "smallest unstable step (ms)"), 1e3
    else:
        heads, scale = ("loosest stable accuracy", "tightest unstable accuracy"), 1.0
    limits = table("integrator", *heads, "checks")
    for lim in outcome.limits:
        limits.add_row(
            lim.integrator,
            "none" if lim.largest_stable is None else f"{lim.largest_stable * scale:.3g}",
            "none" if lim.smallest_unstable is None else f"{lim.smallest_unstable * scale:.3g}",
            str(lim.checks),
        )
    out.print(limits)
