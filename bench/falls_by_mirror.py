"""Falls and mean speed of an evaluation split by whether each episode's clock was mirrored
(left and right legs swapped, ``task.imitate.init.mirror``): a policy trained without mirror
images may run well on one side and fall on the other. Reads ``gaitforge evaluate
--json-out`` files (deterministic mode) and draws each episode's mirroring again from its
seed with the scene's own reset.

Usage: python bench/falls_by_mirror.py EVAL.json [EVAL.json ...] [--scene run-2d+clock]
           [--out split.json]

``--scene`` is the scene whose resets decide the mirroring (the evaluation's scene by
default; give a catalogue scene with the same ``init`` when it was judged on a file).
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
from pathlib import Path
from typing import Any

from gaitforge.workers.env import MuscleEnv
from rich.console import Console
from rich.table import Table


@functools.cache
def _clocked_env(scene: str) -> MuscleEnv:
    """One env per scene for all the reports (building one compiles its simulator)."""
    env = MuscleEnv(scene)
    if env.imitation is None:
        raise SystemExit(f"--scene {scene}: no imitation clock, so nothing is mirrored")
    return env


def mirrored_by_seed(scene: str, seeds: list[int]) -> dict[int, bool]:
    """Whether the reset with each seed mirrors the clock (the env's own draw)."""
    env = _clocked_env(scene)
    return {seed: bool(env.reset(seed=seed)[1]["imitation"]["mirrored"]) for seed in seeds}


def split(report: dict[str, Any], scene: str) -> dict[str, dict[str, float]]:
    """{"mirrored" | "not mirrored": {episodes, fall_rate (fraction), speed (m/s, the mean of
    the episodes' distance / time)}} of a report's deterministic episodes."""
    episodes = report["results"]["deterministic"]["episodes"]
    mirrored = mirrored_by_seed(scene, [e["seed"] for e in episodes])
    groups: dict[str, list[dict[str, Any]]] = {"mirrored": [], "not mirrored": []}
    for episode in episodes:
        groups["mirrored" if mirrored[episode["seed"]] else "not mirrored"].append(episode)
    return {
        name: {
            "episodes": len(group),
            "fall_rate": sum(e["fell"] for e in group) / len(group),
            "speed": statistics.mean(e["mean_speed_m_s"] for e in group),
        }
        for name, group in groups.items()
        if group
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reports", type=Path, nargs="+", help="gaitforge evaluate --json-out files")
    parser.add_argument("--scene", default=None, help="the scene that decides the mirroring")
    parser.add_argument("--out", type=Path, default=None, help="write the split as JSON")
    args = parser.parse_args()
    table = Table(title="deterministic episodes by the clock's mirroring: falls, mean speed")
    for column in ("evaluation", "episodes", "mirrored", "not mirrored"):
        table.add_column(column, justify="left" if column == "evaluation" else "right")
    results = {}
    for path in args.reports:
        report = json.loads(path.read_text())
        parts = results[str(path)] = split(report, args.scene or report["scene"])
        cells = [
            f"{100 * p['fall_rate']:.1f} % at {p['speed']:.2f} ({p['episodes']})" if p else "-"
            for p in (parts.get("mirrored"), parts.get("not mirrored"))
        ]
        table.add_row(str(path), str(sum(p["episodes"] for p in parts.values())), *cells)
    Console(width=160).print(table)
    if args.out is not None:
        args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
