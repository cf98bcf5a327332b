"""Probes: step an env with random excitations and count what happens (speed and numerical
health); this process's resident memory."""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from gaitforge.workers.env import MuscleEnv


@dataclass
class ProbeResult:
    """Totals of a random-excitation run.

    Attributes:
        steps: env (control) steps taken.
        wall_s: wall-clock time spent stepping (resets included), s.
        sim_s: simulated time covered, s.
        episodes: episodes ended (terminated or truncated).
        health: cause -> count of episodes ended by a simulator failure.
        falls: episodes ended by the pelvis dropping below the scene's height.
    """

    steps: int = 0
    wall_s: float = 0.0
    sim_s: float = 0.0
    episodes: int = 0
    falls: int = 0
    health: Counter = field(default_factory=Counter)

    @property
    def steps_per_s(self) -> float:
        return self.steps / self.wall_s if self.wall_s else 0.0

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s else 0.0


def random_excitations(
    env: MuscleEnv,
    seconds: float,
    seed: int = 0,
    on_step: Callable[[ProbeResult], None] | None = None,
) -> ProbeResult:
    """Run uniform random excitations in [0, 1] for ``seconds`` of wall-clock time."""
    rng = np.random.default_rng(seed)
    result = ProbeResult()
    n = env.action_space.shape[0]
    start = time.perf_counter()
    env.reset(seed=seed)
    while (elapsed := time.perf_counter() - start) < seconds:
        _, _, terminated, truncated, info = env.step(rng.uniform(0.0, 1.0, n))
        result.steps += 1
        result.sim_s += env.dt
        if terminated or truncated:
            result.episodes += 1
            if info["health"] != "ok":
                result.health[info["health"]] += 1
            elif info.get("fell"):
                result.falls += 1
            env.reset()
        if on_step is not None and result.steps % 50 == 0:
            result.wall_s = elapsed
            on_step(result)
    result.wall_s = time.perf_counter() - start
    return result


def process_rss_mib() -> float:
    """Resident memory of this process (Linux /proc), MiB."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
