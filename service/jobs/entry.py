"""The trainer process of a service job (the fixed Ray job entrypoint; no user supplies one):

    python -m gaitforge.service.jobs.entry --job-dir DIR [--evaluate-episodes N] [--no-video]

It trains ``DIR/job.yaml`` into ``DIR/run`` (resuming from the newest checkpoint there),
logs to stdout and ``DIR/log.txt`` (appended: a resumed attempt continues the log), and
reports through ``DIR/progress.json`` (phase ``starting`` at once, then every iteration and
every few seconds) and ``DIR/metrics.jsonl`` (a line per iteration). Ends:

- training finished: the final checkpoint evaluated deterministically (``N`` episodes,
  default 5) into ``reports/evaluate-<ckpt>.json``, ``evaluation/<ckpt>.mcap`` and ``.mp4``;
  phase ``finished``, exit 0;
- SIGTERM/SIGINT or the file ``DIR/cancel``: the last update is checkpointed,
  phase ``stopped``, exit 0 (a second signal: at once, phase ``stopped``, exit 0);
- an exception: phase ``failed`` with the error (one line) and traceback, exit 1.

Under a Ray job (``RAY_ADDRESS`` set by Ray) its rollout actors join that cluster.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import socket
import sys
import threading
import traceback
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.progress import (
    JobProgress,
    RuleProgress,
    StageProgress,
    append_metrics,
    jsonable,
    now,
    trim_metrics,
    write_progress,
)
from gaitforge.service.signals import SignalStop

if TYPE_CHECKING:
    from gaitforge.learner.evaluation.results import EvaluationReport
    from gaitforge.service.ops.train import Training

logger = logging.getLogger("gaitforge.service.jobs.entry")
HEARTBEAT_S = 5.0
"""s between rewrites of progress.json while nothing else changes (its age shows life)"""
LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


class Reporter:
    """Holds the job's :class:`JobProgress` and writes it on every change and every
    :data:`HEARTBEAT_S` seconds (thread-safe)."""

    def __init__(self, layout: JobLayout) -> None:
        self.layout = layout
        names = layout.checkpoint_names()
        self.progress = JobProgress(
            phase="starting",
            pid=os.getpid(),
            host=socket.gethostname(),
            updated_at=now(),
            checkpoint=names[-1] if names else None,
        )
        self._lock = threading.Lock()
        self._done = threading.Event()
        self.update()
        threading.Thread(target=self._beat, name="progress-heartbeat", daemon=True).start()

    def update(self, **fields: Any) -> None:
        with self._lock:
            self.progress = self.progress.model_copy(update={**fields, "updated_at": now()})
            write_progress(self.layout.progress_file, self.progress)

    def finish(self, **fields: Any) -> None:
        """The last update: the heartbeat stops."""
        self._done.set()
        self.update(**fields)

    def _beat(self) -> None:
        while not self._done.wait(HEARTBEAT_S):
            try:
                self.update()
            except OSError as exc:  # a full disk must not kill the trainer from here
                logger.warning("progress.json: %s", exc)


class IterationReport:
    """The ``on_iteration`` callback: metrics.jsonl, progress.json, status lines, and the
    cancel file (-> ``training.request_stop()``)."""

    def __init__(self, layout: JobLayout, reporter: Reporter, training: Training) -> None:
        from gaitforge.service.ops.train import ProgressLog

        self.layout, self.reporter, self.training = layout, reporter, training
        self.log = ProgressLog(every_s=5.0)
        self.cancelled = False

    def __call__(self, metrics: dict) -> None:
        append_metrics(self.layout.metrics_file, metrics)
        names = self.layout.checkpoint_names()
        self.reporter.update(
            phase="training",
            iteration=metrics["iteration"],
            env_steps=metrics["env_steps"],
            steps_per_s=jsonable(metrics["steps_per_s"]),
            stage=self.stage(metrics),
            metrics=jsonable(metrics),
            checkpoint=names[-1] if names else None,
        )
        self.log(metrics)
        if not self.cancelled and self.layout.cancel_file.exists():
            self.cancelled = True
            logger.warning("cancel requested: stopping after this iteration, with a checkpoint")
            self.training.request_stop()

    def stage(self, metrics: dict) -> StageProgress:
        """The stage of ``metrics`` and each promotion rule's window mean against its target
        (called before the trainer moves on to the next stage)."""
        job, curriculum = self.training.job, self.training.trainer.curriculum
        index = metrics["stage"]
        stage = job.stages[index]
        episodes = len(curriculum.episodes)
        rules = []
        for rule in stage.promote:
            value = jsonable(curriculum.window_mean(rule.metric, rule.window))
            full = episodes >= rule.window
            rules.append(
                RuleProgress(
                    rule=str(rule),
                    metric=rule.metric,
                    op=rule.op,
                    target=rule.value,
                    window=rule.window,
                    episodes=min(episodes, rule.window),
                    value=value,
                    passing=full and value is not None and rule.passes(value),
                )
            )
        return StageProgress(
            index=index,
            name=metrics["stage_name"],
            scene=metrics["scene"],
            count=len(job.stages),
            env_steps=metrics["stage_env_steps"],
            budget_env_steps=stage.env_steps,
            promote=rules,
        )


def within_job(report: EvaluationReport, job_dir: Path) -> EvaluationReport:
    """``report`` with its file names (checkpoint, recording, video) relative to the job's
    folder: a served report does not show the server's directories."""

    def relative(name: str | None) -> str | None:
        if name is None or not Path(name).is_relative_to(job_dir):
            return name
        return str(Path(name).relative_to(job_dir))

    return dataclasses.replace(
        report,
        checkpoint=relative(report.checkpoint),
        recording=relative(report.recording),
        video=relative(report.video),
    )


def evaluate_final(layout: JobLayout, reporter: Reporter, episodes: int, video: bool) -> None:
    """Evaluate the newest checkpoint deterministically: report JSON, MCAP and (if ``video``
    and rendering works here) MP4 of the first episode. A failing video is logged and the
    evaluation done again without it."""
    from gaitforge.service.ops import evaluate as ops
    from gaitforge.service.ops.train import newest_checkpoint

    checkpoint = newest_checkpoint(layout.run_dir)
    if checkpoint is None:
        raise RuntimeError(f"{layout.run_dir}: training finished without a checkpoint")
    reporter.update(phase="evaluating", checkpoint=checkpoint.name)
    layout.evaluation_dir.mkdir(parents=True, exist_ok=True)
    record = layout.evaluation_dir / f"{checkpoint.name}.mcap"
    movie = layout.evaluation_dir / f"{checkpoint.name}.mp4" if video else None
    logger.info("evaluating %s: %d deterministic episode(s)", checkpoint.name, episodes)

    def request(movie: Path | None) -> ops.EvaluateRequest:
        return ops.EvaluateRequest(
            checkpoint=checkpoint,
            episodes=episodes,
            modes=["deterministic"],
            record=record,
            video=movie,
        )

    try:
        report = ops.evaluate(request(movie))
    except Exception as exc:
        if movie is None:
            raise
        logger.warning("the video failed (%s); evaluating again without it", exc)
        movie.unlink(missing_ok=True)
        report = ops.evaluate(request(None))
    path = layout.reports_dir / f"evaluate-{checkpoint.name}.json"
    ops.write_report(within_job(report, layout.dir), path)
    logger.info("evaluation report: %s", path)


def train(layout: JobLayout, reporter: Reporter, signals: SignalStop) -> bool:
    """Train the job until it finishes or is stopped; True if it finished."""
    from gaitforge.service.ops import train as ops  # lazy: torch, MuJoCo (seconds)

    request = ops.TrainRequest(job_file=layout.job_file, run_dir=layout.run_dir, tensorboard=True)
    training = ops.prepare_training(request)
    trim_metrics(layout.metrics_file, training.trainer.iteration)  # resumed at that iteration
    try:
        if training.start_ray():
            signals.install()  # Ray's driver put in its own handlers: take them back
        logger.info("%s", ops.start_line(training))
        reporter.update(phase="training")
        report = IterationReport(layout, reporter, training)
        signals.on_stop(training.request_stop)
        if layout.cancel_file.exists():
            report.cancelled = True
            training.request_stop()
        result = training.run(on_iteration=report)
    finally:
        training.close()
    names = layout.checkpoint_names()
    reporter.update(
        iteration=result.iteration,
        env_steps=result.env_steps,
        checkpoint=names[-1] if names else None,
    )
    return result.finished


def configure_logging(log_file: Path) -> None:
    """INFO and up from gaitforge (WARNING from others) to stdout and ``log_file``."""
    formatter = logging.Formatter(LOG_FORMAT)
    root = logging.getLogger()
    for handler in (logging.StreamHandler(sys.stdout), logging.FileHandler(log_file, "a")):
        handler.setFormatter(formatter)
        root.addHandler(handler)
    root.setLevel(logging.WARNING)
    logging.getLogger("gaitforge").setLevel(logging.INFO)
    logging.captureWarnings(True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gaitforge.service.jobs.entry")
    parser.add_argument("--job-dir", type=Path, required=True, help="<artifacts>/jobs/<id>")
    parser.add_argument("--evaluate-episodes", type=int, default=5, help="episodes (>= 1)")
    parser.add_argument("--no-video", action="store_true", help="no MP4 of the evaluation")
    args = parser.parse_args(argv)
    if args.evaluate_episodes < 1:
        parser.error("--evaluate-episodes: must be 1 or more")
    job_dir = args.job_dir.resolve()
    layout = JobLayout(job_dir.parent.parent, job_dir.name)
    if layout.dir != job_dir or not layout.job_file.is_file():
        parser.error(f"--job-dir: {args.job_dir}: expected <artifacts>/jobs/<id> with job.yaml")
    signals = SignalStop()
    signals.install()  # a signal while starting is remembered
    reporter = Reporter(layout)
    configure_logging(layout.log_file)
    logger.info(
        "trainer process %d on %s: job %s (%s)",
        os.getpid(),
        reporter.progress.host,
        os.environ.get("GAITFORGE_JOB_ID", layout.job_id),
        layout.dir,
    )
    try:
        finished = train(layout, reporter, signals)
        if finished and not signals.received:
            evaluate_final(layout, reporter, args.evaluate_episodes, not args.no_video)
            reporter.finish(phase="finished")
            logger.info("finished")
        else:
            reporter.finish(phase="stopped")
            logger.info("stopped; newest checkpoint: %s", reporter.progress.checkpoint)
        return 0
    except KeyboardInterrupt:  # a second signal: stop at once
        names = layout.checkpoint_names()
        reporter.finish(phase="stopped", checkpoint=names[-1] if names else None)
        logger.warning("stopped at once; newest checkpoint: %s", reporter.progress.checkpoint)
        return 0
    except Exception as exc:
        text = str(exc).splitlines()[0] if str(exc).strip() else type(exc).__name__
        error = text if _is_user_error(exc) else f"{type(exc).__name__}: {text}"
        logger.exception("failed: %s", error)
        reporter.finish(phase="failed", error=error, traceback=traceback.format_exc())
        return 1
    finally:
        signals.restore()


def _is_user_error(exc: Exception) -> bool:
    """Errors whose message says it all (a bad job or checkpoint, one line)."""
    from gaitforge.workers.spec_io import SpecError

    return isinstance(exc, SpecError) or type(exc).__name__ in {
        "CheckpointError",
        "EvaluationError",
    }


if __name__ == "__main__":
    sys.exit(main())
