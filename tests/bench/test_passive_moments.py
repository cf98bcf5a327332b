"""bench/passive_moments.py: the relaxed muscles' joint moments on MuJoCo (per
muscle_passive option) and OpenSim, the body in the air, the ankle swept (real simulators)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench


def test_standing_the_default_fit_pulls_as_opensim_and_thelen_harder(
    tmp_path: Path, run_bench: RunBench
) -> None:
    """At the standing ankle (0 deg) MuJoCo's default passive fit and OpenSim agree on the
    relaxed ankle moment within 15 % (-79 against -82 N m); the whole-strain fit pulls harder
    (-127); bent up 10 deg, OpenSim's moment is more than the default's (-249 against -160)."""
    out = tmp_path / "moments.json"
    done = run_bench(
        "passive_moments.py", "--scene", "walk-2d+clock", "--degrees", "0", "10",
        "--options", "gait", "thelen", "--json-out", str(out),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    data = json.loads(out.read_text())
    ankle = data["joints"].index("ankle_angle_r")
    moment = {name: [row[ankle] for row in rows] for name, rows in data["moments_n_m"].items()}
    opensim, gait, thelen = moment["opensim"], moment["mujoco gait"], moment["mujoco thelen"]
    assert abs(gait[0] - opensim[0]) < 0.15 * abs(opensim[0])
    assert thelen[0] < 1.3 * opensim[0] < 0  # harder (more negative) standing
    assert opensim[1] < 1.3 * gait[1] < 0  # OpenSim's the harder bent up


def test_an_unknown_option_is_refused_with_the_allowed_ones(run_bench: RunBench) -> None:
    done = run_bench("passive_moments.py", "--options", "stiff", timeout_s=120)
    assert done.returncode != 0 and "thelen-fibre" in done.stderr
