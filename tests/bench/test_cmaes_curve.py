"""bench/cmaes_curve.py: a search continued from another's tuned scene is drawn as one
curve, its minutes after the first's."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from cmaes_curve import read_joined

if TYPE_CHECKING:
    from conftest import RunBench

HEADER = "generation,best,mean,sigma,best_alive,best_speed,wall_s\n"


def write(path: Path, rows: list[tuple[float, ...]]) -> str:
    path.write_text(HEADER + "".join(",".join(map(str, row)) + "\n" for row in rows))
    return str(path)


def test_a_continuation_follows_its_first_search(tmp_path: Path, run_bench: RunBench) -> None:
    first = write(
        tmp_path / "a.csv",
        [(1, 1.5, 1.8, 0.1, 0.2, 0.1, 10.0), (2, 1.2, 1.6, 0.09, 0.3, 0.2, 21.5)],
    )
    then = write(tmp_path / "b.csv", [(1, 0.9, 1.1, 0.03, 0.6, 0.5, 9.0)])
    joined = read_joined(f"{first}+{then}")
    assert joined["wall_s"] == pytest.approx([10.0, 21.5, 30.5], abs=1e-12)
    assert joined["best"] == pytest.approx([1.5, 1.2, 0.9], abs=1e-12)
    out = tmp_path / "curve.png"
    done = run_bench(
        "cmaes_curve.py", f"{first}+{then}", first, "--labels", "joined", "alone", "--out", str(out)
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert out.stat().st_size > 10_000
