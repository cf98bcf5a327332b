"""``gaitforge train JOB.yaml``: run a job's curriculum on local Ray (or a cluster).

On a terminal, a live display of stage, env steps, speed, return, falls and health (log
lines appear above it); off a terminal (a log file, a service, a batch system), one status
line every ``--log-every`` seconds through ``logging``. SIGINT or SIGTERM drops the batch
being gathered, checkpoints the last update and exits 0 naming it; a second signal stops at
once. The
work is :mod:`gaitforge.service.ops.train`'s; this parses and shows progress.
"""

from __future__ import annotations

import logging
import shlex
import signal
from pathlib import Path
from typing import Annotated

import typer
from gaitforge.learner.curriculum import StageShortfallError
from gaitforge.learner.job import MAX_NUM_WORKERS, Job
from gaitforge.service.cli_options import AsJson, JobSeed, SetFields, assignments
from gaitforge.service.console import err, fail, message, out, print_json
from gaitforge.service.ops import SpecError, validate_request
from gaitforge.service.ops import train as ops
from gaitforge.service.signals import SignalStop
from rich.console import Group
from rich.live import Live
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

STATUS_LOGGERS = ("gaitforge.service", "gaitforge.learner.trainer")
"""loggers raised to INFO while training: status lines, resume, stage ends and entries"""


class TrainDisplay:
    """A progress bar per stage and a table of the newest iteration's metrics."""

    def __init__(self, job: Job, done_steps: list[int]) -> None:
        self.job = job
        self.progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed:,.0f}"),
            TextColumn("/ {task.total:,.0f} env steps"),
            TimeElapsedColumn(),
            console=err,
        )
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
                self.tasks[stage],
                description=f"stage {stage} {metrics['stage_name']} "
                f"[green]{metrics['verdict']}[/green]",
            )

    def __rich__(self) -> Group:
        return Group(self.progress, self._table())

    def _table(self) -> Table:
        m = self.metrics
        table = Table(show_header=False, box=None, padding=(0, 2))
        if not m:
            table.add_row("starting workers ...")
            return table
        if "cmaes_generation" in m:  # a CMA-ES stage
            table.add_row("iteration", f"{m['iteration']}   env steps {m['env_steps']:,}")
            table.add_row(
                "cma-es",
                f"generation {m['cmaes_generation']}   best {m['cmaes_best']:.3f}   mean "
                f"{m['cmaes_mean']:.3f}   sigma {m['cmaes_sigma']:.3f}",
            )
            table.add_row(
                "its best",
                f"alive {100 * m['cmaes_best_alive']:.0f} %   speed {m['cmaes_best_speed']:.2f} "
                f"m/s   falls {100 * m['cmaes_best_falls']:.0f} %",
            )
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
        kl = f"kl {m['approx_kl']:.4f}"
        if "approx_kl_mirrored" in m:
            kl += f" (sampled {m['approx_kl_sampled']:.4f}, mirrored {m['approx_kl_mirrored']:.4g})"
        table.add_row(
            "ppo",
            f"{kl}   entropy {m['entropy']:.2f}   value loss {m['value_loss']:.3g}   "
            f"lr {m['lr']:.2e}",
        )
        table.add_row("health (this batch)", health)
        return table


def resume_command(
    job_file: Path,
    run_dir: Path,
    seed: int | None,
    budget_scale: float,
    set_fields: list[str] | None,
) -> str:
    """The ``gaitforge train`` command that goes on from ``run_dir``'s newest checkpoint with
    the same job: the options that change the job (``--seed``, ``--budget-scale``, ``--set``)
    repeated, each word quoted for a POSIX shell."""
    words = ["gaitforge", "train", str(job_file), "--run-dir", str(run_dir)]
    if seed is not None:
        words += ["--seed", str(seed)]
    if budget_scale != 1.0:
        words += ["--budget-scale", repr(budget_scale)]
    for assignment in set_fields or []:
        words += ["--set", assignment]
    return shlex.join(words)


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
        typer.Option(
            min=0,
            max=MAX_NUM_WORKERS,
            help="Ray rollout actors (0: in-process); overrides the job file",
        ),
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
    max_minutes: Annotated[
        float | None,
        typer.Option(min=1e-3, help="stop (with a checkpoint) after this many minutes of training"),
    ] = None,
    seed: JobSeed = None,
    set_fields: SetFields = None,
    json_out: AsJson = False,
    tensorboard: Annotated[bool, typer.Option(help="write TensorBoard scalars")] = True,
    log_every: Annotated[
        float, typer.Option(min=0.0, help="s between status lines off a terminal (0: each)")
    ] = 10.0,
) -> None:
    """Train a job: its curriculum of stages, with checkpoints, recordings and TensorBoard."""
    for name in STATUS_LOGGERS:
        if logging.getLogger(name).getEffectiveLevel() > logging.INFO:
            logging.getLogger(name).setLevel(logging.INFO)
    signals = SignalStop()
    training: ops.Training | None = None
    try:
        with signals:
            try:
                request = validate_request(
                    ops.TrainRequest,
                    job_file=job_file,
                    run_dir=run_dir,
                    workers=workers,
                    address=address,
                    budget_scale=budget_scale,
                    seed=seed,
                    overrides=assignments(set_fields),
                    tensorboard=tensorboard,
                )
                training = ops.prepare_training(request)
            except SpecError as exc:
                raise fail(exc) from None
            try:
                if training.start_ray():
                    signals.install()  # Ray's driver put in its own handlers: take them back
                signals.on_stop(training.request_stop)
                result = _run(training, max_iterations, max_minutes, log_every, json_out)
            except SpecError as exc:  # a check that needs the cluster: the actors' CPUs
                raise fail(exc) from None
            except (StageShortfallError, _actor_failure()) as exc:
                newest = ops.newest_checkpoint(training.run_dir)
                fail(f"{message(exc)}; newest checkpoint: {newest or 'none'}")
                raise typer.Exit(1) from None
            finally:
                training.close()
    except KeyboardInterrupt:  # a second signal, or Ctrl-C before the handlers were in
        sig = signals.received[-1] if signals.received else signal.SIGINT
        newest = None if training is None else ops.newest_checkpoint(training.run_dir)
        err.print(
            f"{sig.name}: stopped at once; newest checkpoint: {newest or 'none'}",
            soft_wrap=True,
            highlight=False,
        )
        raise typer.Exit(128 + sig.value) from None
    if json_out:
        print_json(result)
        return
    if result.stopped:
        where = result.checkpoint or "none written yet"
        out.print(
            f"{signals.first.name if signals.first else 'stop'}: stopped after iteration "
            f"{result.iteration} ({result.env_steps:,} env steps); checkpoint: {where} "
            f"(resume: {resume_command(job_file, result.run_dir, seed, budget_scale, set_fields)})",
            soft_wrap=True,
            highlight=False,
        )
    out.print(
        f"run directory: {result.run_dir} (tensorboard --logdir {result.run_dir / 'tb'})",
        soft_wrap=True,
        highlight=False,
    )


def _actor_failure() -> type[Exception]:
    """The error a run ends with when its rollout actors keep failing (imported only when
    one is raised: it imports Ray)."""
    from gaitforge.workers.pool import ActorFailureError

    return ActorFailureError


def _run(
    training: ops.Training,
    max_iterations: int | None,
    max_minutes: float | None,
    log_every: float,
    json_out: bool = False,
) -> ops.TrainResult:
    """Train with a live display on a terminal, else with status lines (and the display's
    last state printed at the end, unless the result goes out as JSON)."""
    max_seconds = None if max_minutes is None else 60.0 * max_minutes
    display = TrainDisplay(training.job, training.stage_progress())
    if err.is_terminal:
        with Live(display, console=err, refresh_per_second=4):
            return training.run(max_iterations, max_seconds, on_iteration=display.update)
    log = ops.ProgressLog(every_s=log_every)
    ops.logger.info("%s", ops.start_line(training))

    def on_iteration(metrics: dict) -> None:
        display.update(metrics)
        log(metrics)

    result = training.run(max_iterations, max_seconds, on_iteration=on_iteration)
    if not json_out:
        out.print(display)
    return result
