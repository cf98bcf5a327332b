"""How far a body turns about the vertical when a clock scene's recorded gait is replayed
through its joint targets with no policy (every action 0.5: the targets are the recording's
pose), side by side: as the scene is and with MuJoCo contact settings that stop a foot
creeping on the floor. It separates what the body and the
recipe's base do from what a policy learned (``gaitforge evaluate`` reports a policy's turn).

Usage: python bench/replay_turn.py [--scene walk-3d+clock] [--episodes 10] [--seed 0]
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

import mujoco
import numpy as np
from gaitforge.workers.episode import EpisodeRunner, EpisodeSummary, run_episode
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim.mujoco.build import FLOOR
from rich.console import Console
from rich.table import Table

console = Console(width=120)

ModelChange = Callable[[mujoco.MjModel], None]


def _no_creep(model: mujoco.MjModel) -> None:
    model.opt.noslip_iterations = 20


def _stiff_friction(model: mujoco.MjModel) -> None:
    model.opt.impratio = 10.0


def _torsional_friction(model: mujoco.MjModel) -> None:
    floor = model.geom(FLOOR).id
    model.geom_condim[floor] = 6
    model.geom_friction[floor] = [model.geom_friction[floor][0], 0.02, 0.001]


CONTACT_VARIANTS: dict[str, ModelChange] = {
    "noslip_iterations 20": _no_creep,
    "impratio 10": _stiff_friction,
    "torsional friction (condim 6)": _torsional_friction,
}


def replay(
    scene: Scene, episodes: int, seed: int, change: ModelChange | None = None
) -> list[EpisodeSummary]:
    """``episodes`` replays of ``scene`` from seeds ``seed``.. on MuJoCo, every action 0.5,
    after ``change`` to the compiled model; their summaries."""
    with EpisodeRunner(scene) as runner:
        env = runner.env
        if change is not None:
            change(env.sim.model)
        middle = np.full(env.action_space.shape, 0.5)
        return [run_episode(env, lambda _obs: middle, seed + i) for i in range(episodes)]


def row(label: str, runs: list[EpisodeSummary]) -> list[str]:
    """A table row: the label, episodes, mean time (s), falls, median and range of the
    turn's size (deg)."""
    turns = [abs(math.degrees(r.turned_rad)) for r in runs]
    return [
        label,
        str(len(runs)),
        f"{np.mean([r.time_s for r in runs]):.2f}",
        f"{sum(r.fell for r in runs)}",
        f"{np.median(turns):.0f}",
        f"{min(turns):.0f}-{max(turns):.0f}",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="walk-3d+clock")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    scene = load_scene(args.scene)
    table = Table(
        "replay",
        "episodes",
        "time s",
        "falls",
        "turn deg (median)",
        "turn deg (range)",
        title=f"{args.scene}: the recording replayed, every action 0.5",
    )
    table.add_row(*row("as the scene is", replay(scene, args.episodes, args.seed)))
    for label, change in CONTACT_VARIANTS.items():
        table.add_row(*row(label, replay(scene, args.episodes, args.seed, change)))
    console.print(table)


if __name__ == "__main__":
    main()
