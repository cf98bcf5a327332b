"""bench/results: small summaries only, and the job files kept there for a user to rerun load
as they are (their scenes and ``init_from`` resolved from their own folder)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from gaitforge.learner.job import load_job

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "bench" / "results"
JOBS = sorted(RESULTS.rglob("job.yaml"))


def _tracked() -> list[Path]:
    done = subprocess.run(
        ["git", "ls-files", "-z", "bench/results"], cwd=REPO, capture_output=True, check=True
    )
    return [REPO / name for name in done.stdout.decode().split("\0") if name]


def test_the_jobs_are_there() -> None:
    assert RESULTS / "obstacles-2d/real/sweep-60min/job.yaml" in JOBS


@pytest.mark.parametrize("path", JOBS, ids=lambda p: str(p.relative_to(RESULTS)))
def test_a_kept_job_file_loads(path: Path) -> None:
    job, scenes, _ = load_job(path)  # init_from must be a checkpoint, each scene must load
    assert len(scenes) == len(job.stages)


def test_no_checkpoints_videos_logs_or_scripts_and_about_3_mb() -> None:
    files = _tracked()
    kinds = {".safetensors", ".pt", ".mp4", ".patch", ".sh", ".log", ".py"}
    assert [f for f in files if f.suffix in kinds] == []
    assert sum(f.stat().st_size for f in files if f.exists()) < 3.5e6
