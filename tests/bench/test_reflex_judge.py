"""bench/reflex_judge.py: tuned reflex scenes judged side by side on unseen seeds (real
MuJoCo; 0.3 s episodes, pushed)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from conftest import RunBench


def test_two_tuned_scenes_are_judged_side_by_side(tmp_path: Path, run_bench: RunBench) -> None:
    scenes = []
    for name, lean in (("upright", 0.0), ("leaning", 0.25)):
        path = tmp_path / f"{name}.yaml"
        path.write_text(
            f"name: {name}\nbase: reflex-walk-3d\n"
            f"set: {{episode_s: 0.3, action.parameters: {{pose.lean: {lean}}}}}\n"
        )
        scenes.append(str(path))
    out = tmp_path / "judged.json"
    pushes = "pushes={force_n: [50, 60], every_s: [0.2, 0.2]}"  # one push in each episode
    done = run_bench(
        "reflex_judge.py", *scenes, "--episodes", "2", "--set", pushes, "--json", str(out)
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "upright.yaml" in done.stdout and "leaning.yaml" in done.stdout
    results = json.loads(out.read_text())
    for figures in results.values():
        assert figures["episodes"] == 2
        assert 0.0 <= figures["falls"] <= 1.0
        assert 0.0 < figures["alive_s"] <= 0.3 + 1e-9
        assert 0 < figures["env_steps"] <= 2 * 30
    refused = run_bench("reflex_judge.py", scenes[0], "--set", "pushes={force_n: [80, 60]}")
    assert refused.returncode != 0 and "force_n must be (low, high)" in refused.stderr
