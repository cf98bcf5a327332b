"""The anchors' progress beside gaitforge's (``bench/myoleg_anchors/plot_progress.py``): an
anchor's rows read in training minutes and seconds of episode, rows without an ended episode
left out, a gaitforge run read off its TensorBoard scalars, and the PNG written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from torch.utils.tensorboard import SummaryWriter

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "bench" / "myoleg_anchors" / "plot_progress.py"
sys.path.insert(0, str(SCRIPT.parent))

from plot_progress import anchor_curve, gaitforge_curve  # noqa: E402

PROGRESS = """wall_s,env_steps,episodes,mean_return,mean_length
30.0,15000,400,57.3,40.0
60.0,30000,0,,
90.0,45000,300,101.8,55.5
"""


@pytest.fixture
def anchor_run(tmp_path: Path) -> Path:
    run = tmp_path / "sb3-s0"
    run.mkdir()
    (run / "progress.csv").write_text(PROGRESS)
    return run


@pytest.fixture
def gaitforge_run(tmp_path: Path) -> Path:
    run = tmp_path / "gaitforge"
    writer = SummaryWriter(str(run / "tb"))
    for step, (seconds, length) in enumerate([(120.0, 0.8), (240.0, 1.1)], start=1):
        writer.add_scalar("train/stage", 0, step)
        writer.add_scalar("train/train_s", seconds, step)
        writer.add_scalar("train/length", length, step)
    writer.close()
    return run


def test_an_anchor_run_reads_in_minutes_and_seconds_of_episode(anchor_run: Path) -> None:
    minutes, lengths = anchor_curve(anchor_run)
    assert minutes == pytest.approx([0.5, 1.5])
    assert lengths == pytest.approx([0.4, 0.555])


def test_a_gaitforge_run_reads_off_its_scalars(gaitforge_run: Path) -> None:
    minutes, lengths = gaitforge_curve(gaitforge_run)
    assert minutes == pytest.approx([2.0, 4.0])
    assert lengths == pytest.approx([0.8, 1.1])


def test_the_plot_is_written_and_a_bad_pair_is_named(
    anchor_run: Path, gaitforge_run: Path, tmp_path: Path
) -> None:
    out = tmp_path / "progress.png"
    args = [sys.executable, str(SCRIPT), "--anchor", f"sb3={anchor_run}"]
    done = subprocess.run(
        [*args, "--gaitforge", f"ours={gaitforge_run}", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    bad = subprocess.run(
        [*args, "--gaitforge", str(gaitforge_run), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode != 0 and "--gaitforge" in bad.stderr
