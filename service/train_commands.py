"""``gaitforge train JOB.yaml``: run a job's curriculum on local Ray (or a cluster) with a
live display of stage, env steps, speed, return, falls and health."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Annotated

import typer
from gaitforge.learner.job import Job, load_job
from gaitforge.workers.spec_io import SpecError
from rich.console import Console, Group
from rich.live import Live
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

console = Console()


class TrainDisplay:
    """A progress bar per stage and a table of the newest iteration's metrics."""

    def __init__(self, job: Job, done_steps: list[int]) -> None:
        self.job = job
        self.progress = Progress(
            TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:,.0f}"),
            TextColumn("/ {task.total:,.0f} env steps"), TimeElapsedColumn(), console=console,
        )  # fmt: skip
        self.tasks = [
            self.progress.add_task(
                f"stage {i} {s.name or s.scene}", total=s.env_steps, completed=done_steps[i]
            )
            for i, s in enumerate(job.stages)
        ]
        self.metrics: dict = {}

    def update(self, metrics: dict) -> None:
        self.metrics = metrics
        stage = metrics["stage"]
        self.progress.update(self.tasks[stage], completed=metrics["stage_env_steps"])
        if metrics["verdict"]:
            self.progress.update(
                self.tasks[stage], description=f"stage {stage} {metrics['stage_name']} "
                f"[green]{metrics['verdict']}[/green]",
            )  # fmt: skip

    def __rich__(self) -> Group:
        return Group(self.progress, self._table())

    def _table(self) -> Table:
        m = self.metrics
        table = Table(show_header=False, box=None, padding=(0, 2))
        if not m:
            table.add_row("starting workers ...")
            return table
        alpha = "" if m["alpha"] is None else f"   blend alpha {m['alpha']:.2f}"
        health = ", ".join(f"{k} {v}" for k, v in m["health"].items()) or "ok"
        table.add_row("iteration", f"{m['iteration']}   env steps {m['env_steps']:,}{alpha}")
        table.add_row(
            "steps/s", f"{m['steps_per_s']:,.0f} (sampling {m['sample_steps_per_s']:,.0f})"
        )
        table.add_row(
            "episodes (last 100)",
            f"return {m['return']:.1f}   distance {m['distance']:.2f} m   speed "
            f"{m['speed']:.2f} m/s   falls {100 * m['fall_rate']:.0f} %   survival "
            f"{100 * m['survival']:.0f} %",
        )
        table.add_row("ppo", f"kl {m['approx_kl']:.4f}   entropy {m['entropy']:.2f}   "
                      f"value loss {m['value_loss']:.3g}   lr {m['lr']:.2e}")  # fmt: skip
        table.add_row("health (this batch)", health)
        return table


def train(
    job_file: Annotated[Path, typer.Argument(help="job YAML (see examples/)")],
    run_dir: Annotated[
        Path | None,
        typer.Option(
            help="checkpoints, TensorBoard and recordings; resumes "
            "from its latest checkpoint [default: runs/<job name>]"
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(min=0, help="Ray rollout actors (0: in-process); overrides the job file"),
    ] = None,
    address: Annotated[
        str | None, typer.Option(help="Ray cluster address to join (e.g. auto)")
    ] = None,
    budget_scale: Annotated[
        float, typer.Option(min=1e-6, max=100.0, help="multiply every stage's env-step budget")
    ] = 1.0,
    max_iterations: Annotated[
        int | None, typer.Option(min=1, help="stop after this many PPO updates")
    ] = None,
    tensorboard: Annotated[bool, typer.Option(help="write TensorBoard scalars")] = True,
) -> None:
    """Train a job: its curriculum of stages, with checkpoints, recordings and TensorBoard."""
    from gaitforge.learner.trainer import Trainer  # lazy: torch

    try:
        job, scenes = load_job(job_file)
        job = _override(job, workers, address, budget_scale)
        run_dir = run_dir or Path("runs") / job.name
        trainer = Trainer(job, run_dir, scenes, tensorboard=tensorboard)
    except SpecError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True, highlight=False)
        raise typer.Exit(2) from None
    done = [0] * len(job.stages)
    for i in range(min(trainer.curriculum.stage, len(job.stages))):
        done[i] = job.stages[i].env_steps
    if not trainer.done:
        done[trainer.curriculum.stage] = trainer.curriculum.stage_env_steps
    display = TrainDisplay(job, done)
    trainer.on_iteration = display.update
    logging.getLogger("workers").setLevel(logging.WARNING)
    with Live(display, console=console, refresh_per_second=4):
        trainer.run(max_iterations=max_iterations)
    console.print(f"run directory: {run_dir} (tensorboard --logdir {run_dir / 'tb'})")


def _override(job: Job, workers: int | None, address: str | None, scale: float) -> Job:
    """The job with the command line's overrides applied (and validated again)."""
    raw = job.model_dump()
    if workers is not None:
        raw["workers"]["num_workers"] = workers
    if address is not None:
        raw["workers"]["ray_address"] = address
    for stage in raw["stages"]:
        stage["env_steps"] = max(1, round(stage["env_steps"] * scale))
        if stage["blend"] is not None:
            stage["blend"]["ramp_env_steps"] = max(
                1, round(stage["blend"]["ramp_env_steps"] * scale)
            )
    return Job.model_validate(raw)
