"""Env steps/s on one core for every catalogue scene, and walk-3d pruned against full MyoLeg.

Usage: python bench/env_speed.py [--seconds S] [--repeats R]

Each scene runs random excitations for S wall-clock seconds, R times interleaved, and the
median is reported. The pruning comparison steps the same MuJoCo model physics (no env
overhead) for the pruned walk-3d model and for MyoLeg with nothing removed, alternating
the two in one run so that machine noise hits both alike; the ratio is the figure to quote.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np
from rich.console import Console
from rich.table import Table

from workers.env import MuscleEnv
from workers.probe import random_excitations
from workers.scenes import catalogue, load_scene
from workers.sim.mujoco import INTEGRATORS, MujocoSimulator, source_spec

console = Console()


def physics_steps_per_s(model: mujoco.MjModel, seconds: float, seed: int = 0) -> float:
    """Raw mj_step rate under uniform random controls held for 10 ms each."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    n_sub = max(1, round(0.01 / model.opt.timestep))
    steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        data.ctrl[:] = rng.uniform(0, 1, model.nu)
        mujoco.mj_step(model, data, nstep=n_sub)
        steps += n_sub
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            mujoco.mj_resetData(model, data)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    console.print(
        f"machine: {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, mujoco {mujoco.__version__}"
    )

    table = Table(
        "scene",
        "dofs",
        "muscles",
        "contact pairs",
        "env steps/s",
        "real-time x",
        title="Env steps/s, one core, random excitations (median)",
    )
    for name in catalogue():
        env = MuscleEnv(name)
        runs = [random_excitations(env, args.seconds, seed=r) for r in range(args.repeats)]
        best = sorted(runs, key=lambda r: r.steps_per_s)[len(runs) // 2]
        size = env.sim.report.size
        table.add_row(
            name,
            str(size["dofs"]),
            str(size["muscles"]),
            str(size["contact_pairs"]),
            f"{best.steps_per_s:.0f}",
            f"{best.realtime_factor:.1f}",
        )
    console.print(table)

    scene = load_scene("walk-3d")
    pruned = MujocoSimulator(scene).model
    full_spec = source_spec("myoleg")
    profile = scene.profile("mujoco")
    full_spec.option.integrator = INTEGRATORS[profile.integrator]
    full_spec.option.timestep = profile.timestep
    full = full_spec.compile()
    rates: dict[str, list[float]] = {"full MyoLeg": [], "walk-3d pruned": []}
    for r in range(args.repeats):
        rates["full MyoLeg"].append(physics_steps_per_s(full, args.seconds, r))
        rates["walk-3d pruned"].append(physics_steps_per_s(pruned, args.seconds, r))
    cmp = Table(
        "model",
        "dofs",
        "muscles",
        "contact pairs",
        "physics steps/s",
        "ratio",
        title=f"Pruning: walk-3d against full MyoLeg ({profile.integrator}, "
        f"{profile.timestep * 1000:g} ms)",
    )
    base = statistics.median(rates["full MyoLeg"])
    report = MujocoSimulator(scene).report
    for label, model_size in (("full MyoLeg", report.size_full), ("walk-3d pruned", report.size)):
        rate = statistics.median(rates[label])
        cmp.add_row(
            label,
            str(model_size["dofs"]),
            str(model_size["muscles"]),
            str(model_size["contact_pairs"]),
            f"{rate:.0f}",
            f"{rate / base:.2f}",
        )
    console.print(cmp)


if __name__ == "__main__":
    main()
