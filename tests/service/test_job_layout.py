"""A job's folder: artifacts listed and resolved by exact name only (no traversal, no
links out), progress.json replaced atomically, metrics.jsonl read without a torn line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.progress import (
    JobProgress,
    RuleProgress,
    StageProgress,
    append_metrics,
    jsonable,
    now,
    read_metrics,
    read_progress,
    trim_metrics,
    write_progress,
)


def _job(tmp_path: Path) -> JobLayout:
    layout = JobLayout(tmp_path / "artifacts", "j-0123456789ab")
    for name in ("ckpt-000000001024", "ckpt-000000002048"):
        (layout.checkpoints_dir / name).mkdir(parents=True)
        (layout.checkpoints_dir / name / "manifest.json").write_text("{}")
    (layout.checkpoints_dir / ".tmp-half").mkdir()  # being written: not listed
    (layout.checkpoints_dir / "ckpt-000000003072").mkdir()  # no manifest yet: not listed
    layout.recordings_dir.mkdir(parents=True)
    (layout.recordings_dir / "ckpt-000000001024-stand-2d.mcap").write_bytes(b"mcap")
    layout.evaluation_dir.mkdir()
    (layout.evaluation_dir / "ckpt-000000002048.mcap").write_bytes(b"mcap")
    (layout.evaluation_dir / "ckpt-000000002048.mp4").write_bytes(b"mp4")
    layout.reports_dir.mkdir()
    (layout.reports_dir / "evaluate-ckpt-000000002048.json").write_text("{}")
    (tmp_path / "artifacts" / "secret.json").write_text("{}")
    return layout


def test_paths_and_listings(tmp_path: Path) -> None:
    layout = _job(tmp_path)
    assert layout.dir == tmp_path / "artifacts" / "jobs" / "j-0123456789ab"
    assert layout.job_file.parent == layout.dir and layout.run_dir == layout.dir / "run"
    assert layout.checkpoint_names() == ["ckpt-000000001024", "ckpt-000000002048"]
    assert [p.name for p in layout.recording_files()] == [
        "ckpt-000000001024-stand-2d.mcap",
        "ckpt-000000002048.mcap",
        "ckpt-000000002048.mp4",
    ]
    assert layout.artifact_names("reports") == ["evaluate-ckpt-000000002048.json"]
    assert layout.resolve_artifact("checkpoints", "ckpt-000000002048").is_dir()
    assert layout.resolve_artifact("recordings", "ckpt-000000002048.mp4").read_bytes() == b"mp4"
    assert JobLayout(tmp_path, "j-ffffffffffff").checkpoint_names() == []


@pytest.mark.parametrize(
    "kind,name",
    [
        ("reports", "../../secret.json"),
        ("reports", "..%2F..%2Fsecret.json"),
        ("reports", "%252e%252e%252fsecret.json"),
        ("reports", "/etc/passwd"),
        ("reports", str(Path("/") / "etc" / "passwd")),
        ("checkpoints", "ckpt-000000003072"),
        ("checkpoints", ".tmp-half"),
        ("checkpoints", "ckpt-000000001024/manifest.json"),
        ("recordings", "../run/recordings/ckpt-000000001024-stand-2d.mcap"),
        ("secrets", "secret.json"),
        ("reports", ""),
    ],
)
def test_only_listed_names_resolve(tmp_path: Path, kind: str, name: str) -> None:
    assert _job(tmp_path).resolve_artifact(kind, name) is None


def test_a_link_out_of_the_job_is_not_served(tmp_path: Path) -> None:
    layout = _job(tmp_path)
    (layout.reports_dir / "leak.json").symlink_to(tmp_path / "artifacts" / "secret.json")
    assert "leak.json" in layout.artifact_names("reports")
    assert layout.resolve_artifact("reports", "leak.json") is None


@pytest.mark.parametrize("job_id", ["../x", "a/b", "", ".hidden", "j-01\n"])
def test_bad_job_ids_are_refused(tmp_path: Path, job_id: str) -> None:
    with pytest.raises(ValueError, match="job_id"):
        JobLayout(tmp_path, job_id)


def test_progress_round_trip_and_atomic_replace(tmp_path: Path) -> None:
    path = tmp_path / "progress.json"
    assert read_progress(path) is None
    rule = RuleProgress(
        rule="survival >= 0.95 over 100 episodes",
        metric="survival",
        op=">=",
        target=0.95,
        window=100,
        episodes=12,
        value=0.5,
        passing=False,
    )
    stage = StageProgress(
        index=0,
        name="stand",
        scene="stand-2d",
        count=1,
        env_steps=512,
        budget_env_steps=1024,
        promote=[rule],
    )
    progress = JobProgress(
        phase="training",
        pid=1,
        host="h",
        updated_at=now(),
        iteration=1,
        env_steps=512,
        steps_per_s=900.0,
        stage=stage,
        metrics={"return": 1.5},
        checkpoint="ckpt-000000000512",
    )
    write_progress(path, progress)
    assert read_progress(path) == progress
    assert [p.name for p in tmp_path.iterdir()] == ["progress.json"]  # no temporary left
    path.write_text('{"phase": "trainin')  # a torn file (not written by write_progress)
    assert read_progress(path) is None


def test_metrics_lines_drop_non_finite_and_skip_a_torn_last_line(tmp_path: Path) -> None:
    path = tmp_path / "metrics.jsonl"
    assert read_metrics(path) == []
    for i in range(3):
        append_metrics(
            path,
            {
                "iteration": i + 1,
                "return": np.float32(i),
                "kl": math.nan,
                "health": {"nan_obs": np.int64(2)},
            },
        )
    with path.open("a") as f:
        f.write('{"iteration": 4, "ret')  # being written
    rows = read_metrics(path)
    assert [r["iteration"] for r in rows] == [1, 2, 3]
    assert rows[2] == {"iteration": 3, "return": 2.0, "kl": None, "health": {"nan_obs": 2}}
    assert [r["iteration"] for r in read_metrics(path, start=1, limit=1)] == [2]
    assert json.loads(json.dumps(jsonable({"x": (math.inf, -math.inf)}))) == {"x": [None, None]}


def test_a_resumed_run_trims_the_iterations_after_its_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "metrics.jsonl"
    assert trim_metrics(path, 3) == 0 and not path.exists()
    for i in range(1, 6):
        append_metrics(path, {"iteration": i})
    with path.open("a") as f:
        f.write('{"iteration": 6, "ret')  # torn by a kill
    assert trim_metrics(path, 3) == 3
    assert [r["iteration"] for r in read_metrics(path)] == [1, 2, 3]
    assert path.read_text().endswith("\n")
    assert trim_metrics(path, 3) == 3
