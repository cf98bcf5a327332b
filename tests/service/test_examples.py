"""Every shipped job file loads and checks (scenes, backends, overrides, transitions)."""

from __future__ import annotations

from pathlib import Path

import pytest
from gaitforge.learner.job import load_job

EXAMPLES = sorted((Path(__file__).parents[2] / "examples").glob("*.yaml"))


def test_there_are_examples() -> None:
    names = {p.stem for p in EXAMPLES}
    assert {"elbow-reach", "stand-2d", "walk-2d", "gait2d-curriculum", "walk-3d"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_job_loads(path: Path) -> None:
    job, scenes, _ = load_job(path)
    assert len(scenes) == len(job.stages) and job.name
