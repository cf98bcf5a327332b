"""What the bench scripts' tests share: running a script as a user does."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

RunBench = Callable[..., subprocess.CompletedProcess[str]]


@pytest.fixture
def run_bench() -> RunBench:
    """``run_bench("relaxed_drop.py", "--until-s", "0.03")``: the script under ``bench/`` in
    a fresh interpreter, its output captured as text, tables 200 columns wide (``columns=``),
    stopped after ``timeout_s`` (300 s unless given)."""

    def run(
        script: str, *args: str, timeout_s: float = 300, columns: int = 200
    ) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, str(REPO / "bench" / script), *args],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            env={**os.environ, "COLUMNS": str(columns)},
        )

    return run
