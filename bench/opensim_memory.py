"""Resident memory of an OpenSim env over many episodes, with and without model rebuilds.

Usage: python bench/opensim_memory.py [--episodes 200] [--steps 20] [--scene stand-2d]

OpenSim environments are reported to leak over long runs (osim-rl). Each episode resets
(a new Manager) and takes ``--steps`` random control steps; RSS is sampled after every
episode. The same run is made with the model rebuilt every 25 episodes and never (within
the run), side by side, and the growth per 100 episodes reported for each.
"""

from __future__ import annotations

import argparse
import gc
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.probe import process_rss_mib
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.opensim.simulator import OpenSimSimulator
from rich.console import Console
from rich.progress import track
from rich.table import Table

console = Console()


def run(scene: str, episodes: int, steps: int, rebuild_every: int) -> np.ndarray:
    """RSS (MiB) after each episode."""
    env = MuscleEnv(scene, "opensim")
    env.sim = OpenSimSimulator(load_scene(scene), rebuild_every=rebuild_every)
    rng = np.random.default_rng(0)
    samples = []
    for episode in track(range(episodes), description=f"rebuild every {rebuild_every}"):
        env.reset(seed=episode)
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(rng.uniform(0, 1, env.action_space.shape))
            if terminated or truncated:
                break
        gc.collect()
        samples.append(process_rss_mib())
    return np.array(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--scene", default="stand-2d")
    args = parser.parse_args()
    table = Table(
        "rebuild every",
        "RSS after 10 episodes (MiB)",
        "RSS at end (MiB)",
        "growth per 100 episodes (MiB)",
        title=f"OpenSim {args.scene}: memory",
    )
    for rebuild_every in (args.episodes + 1, 25):
        rss = run(args.scene, args.episodes, args.steps, rebuild_every)
        slope = np.polyfit(np.arange(10, len(rss)), rss[10:], 1)[0] * 100
        label = "never" if rebuild_every > args.episodes else f"every {rebuild_every}"
        table.add_row(label, f"{rss[9]:.1f}", f"{rss[-1]:.1f}", f"{slope:+.2f}")
    console.print(table)


if __name__ == "__main__":
    main()
