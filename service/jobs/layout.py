"""Where a job's files live under the artifact root, and which of them may be downloaded.

    <root>/jobs/<job id>/
        job.yaml            the validated job (inline scenes in scenes/<name>.yaml)
        run/                the trainer's run directory: checkpoints/, recordings/, tb/
        progress.json       the newest ``JobProgress`` (replaced atomically)
        metrics.jsonl       one JSON object per iteration
        log.txt             the trainer's log (every attempt, appended)
        cancel              exists: stop after this iteration
        reports/            evaluation reports (JSON)
        evaluation/         the final evaluation's MCAP and MP4
        downloads/          zips built for download

Artifacts are found by listing these folders; a requested name is looked up among the names
listed, never joined onto a path, so no user text reaches the file system.

The folders the service makes (the artifact root, ``jobs/``, each job's folder) are its
owner's only (0700), as is the service's home (:func:`make_private_dir`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from gaitforge.service.private_files import make_private_dir

ArtifactKind = Literal["checkpoints", "recordings", "reports"]
ARTIFACT_KINDS: tuple[str, ...] = ("checkpoints", "recordings", "reports")
CHECKPOINT_PREFIX = "ckpt-"
"""as ``learner.checkpoint.PREFIX`` (not imported: that imports torch)"""
_JOB_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")


@dataclass(frozen=True)
class JobLayout:
    """The files of job ``job_id`` under ``root`` (the artifact root)."""

    root: Path
    job_id: str

    def __post_init__(self) -> None:
        if not _JOB_ID.fullmatch(self.job_id):
            raise ValueError(f"job_id: {self.job_id!r}: letters, digits, '_' and '-' only")

    @property
    def dir(self) -> Path:
        return self.root / "jobs" / self.job_id

    @property
    def job_file(self) -> Path:
        return self.dir / "job.yaml"

    @property
    def scenes_dir(self) -> Path:
        """inline scenes of the job, ``<name>.yaml``"""
        return self.dir / "scenes"

    @property
    def run_dir(self) -> Path:
        return self.dir / "run"

    @property
    def checkpoints_dir(self) -> Path:
        return self.run_dir / "checkpoints"

    @property
    def recordings_dir(self) -> Path:
        return self.run_dir / "recordings"

    @property
    def progress_file(self) -> Path:
        return self.dir / "progress.json"

    @property
    def metrics_file(self) -> Path:
        return self.dir / "metrics.jsonl"

    @property
    def log_file(self) -> Path:
        return self.dir / "log.txt"

    @property
    def cancel_file(self) -> Path:
        return self.dir / "cancel"

    @property
    def reports_dir(self) -> Path:
        return self.dir / "reports"

    @property
    def evaluation_dir(self) -> Path:
        return self.dir / "evaluation"

    @property
    def downloads_dir(self) -> Path:
        return self.dir / "downloads"

    def create(self) -> Path:
        """Make the job's folder (and the artifact root and ``jobs/`` if missing), its
        owner's only (0700). Returns the folder."""
        return make_private_dir(self.dir)

    def checkpoint_names(self) -> list[str]:
        """Complete checkpoints (``ckpt-<env steps>``, a manifest written), oldest first."""
        if not self.checkpoints_dir.is_dir():
            return []
        return sorted(
            p.name
            for p in self.checkpoints_dir.glob(f"{CHECKPOINT_PREFIX}*")
            if (p / "manifest.json").is_file()
        )

    def recording_files(self) -> list[Path]:
        """The run's MCAP recordings, then the final evaluation's MCAP and MP4 files."""
        return _files(self.recordings_dir, (".mcap",)) + _files(
            self.evaluation_dir, (".mcap", ".mp4")
        )

    def report_files(self) -> list[Path]:
        """Evaluation reports (JSON)."""
        return _files(self.reports_dir, (".json",))

    def artifact_names(self, kind: str) -> list[str]:
        """The names of ``kind``'s artifacts (empty for an unknown kind)."""
        if kind == "checkpoints":
            return self.checkpoint_names()
        if kind == "recordings":
            return [p.name for p in self.recording_files()]
        if kind == "reports":
            return [p.name for p in self.report_files()]
        return []

    def resolve_artifact(self, kind: str, name: str) -> Path | None:
        """The artifact ``name`` of ``kind`` (checkpoints: a directory; otherwise a file),
        if ``name`` is exactly one of :meth:`artifact_names`; None otherwise (a path, an
        encoded name, a name that is not there, an unknown kind)."""
        if kind == "checkpoints":
            found = {n: self.checkpoints_dir / n for n in self.checkpoint_names()}
        elif kind == "recordings":
            found = {}
            for path in self.recording_files():
                found.setdefault(path.name, path)
        elif kind == "reports":
            found = {p.name: p for p in self.report_files()}
        else:
            return None
        path = found.get(name)
        if path is None:
            return None
        try:  # a link out of the job's folder is not served
            path.resolve(strict=True).relative_to(self.dir.resolve())
        except (OSError, ValueError):
            return None
        return path


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    """Plain files in ``folder`` with one of ``suffixes``, by name (hidden ones skipped)."""
    if not folder.is_dir():
        return []
    return sorted(
        p
        for p in folder.iterdir()
        if p.suffix in suffixes and not p.name.startswith(".") and p.is_file()
    )
