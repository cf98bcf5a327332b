"""Task-level error: distributions over seeds on the scene itself, with confidence intervals.

With contact, point-wise trajectories of two profiles diverge for physical reasons (a foot
lands a step earlier), so a sweep compares what a task cares about, over many reset seeds,
under one fixed excitation pattern: distance covered (m), fall rate, and peak ground
reaction (body weights). The runs are also the speed measurement: env steps/s of the
scene over all seeds together (``speed_runs`` repeats them and takes the median).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.fidelity.held import body_excitations, with_profile
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile

Z95 = 1.96
PATTERN_SEED = 1234
"""Seed of the fixed excitation pattern every task run replays."""


def mean_ci(x: np.ndarray) -> tuple[float, float]:
    """Mean and 95% half-width (normal approximation) of ``x``; half-width 0 for n < 2."""
    x = np.asarray(x, dtype=float)
    if len(x) == 0:
        return float("nan"), float("nan")
    half = Z95 * float(np.std(x, ddof=1)) / math.sqrt(len(x)) if len(x) > 1 else 0.0
    return float(np.mean(x)), half


def wilson(k: int, n: int) -> tuple[float, float, float]:
    """Rate ``k/n`` with its 95% Wilson interval (low, high)."""
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    p = k / n
    denom = 1 + Z95**2 / n
    centre = (p + Z95**2 / (2 * n)) / denom
    half = Z95 * math.sqrt(p * (1 - p) / n + Z95**2 / (4 * n * n)) / denom
    return p, max(0.0, centre - half), min(1.0, centre + half)


@dataclass
class TaskStats:
    """Per-seed task outcomes of one profile.

    Attributes:
        distance: [n_seeds] forward pelvis displacement at the end or at the fall, m.
        fell: [n_seeds] whether the episode ended in a fall.
        peak_grf: [n_seeds] largest summed normal ground force, body weights.
        steps: [n_seeds] env steps of each run.
        wall_s: [n_seeds] wall-clock s of each run's steps (one process; resets excluded).
        dt: s, the control period.
        health: cause -> count of runs ended by a simulator failure.
    """

    distance: np.ndarray
    fell: np.ndarray
    peak_grf: np.ndarray
    steps: np.ndarray
    wall_s: np.ndarray
    dt: float
    health: dict[str, int] = field(default_factory=dict)

    @property
    def steps_per_s(self) -> float:
        """Env steps/s over all runs together."""
        return float(self.steps.sum() / self.wall_s.sum()) if self.wall_s.sum() else 0.0

    @property
    def realtime(self) -> float:
        """Simulated s per wall-clock s over all runs together."""
        return self.steps_per_s * self.dt

    def summary(self) -> dict[str, float]:
        d, dh = mean_ci(self.distance)
        g, gh = mean_ci(self.peak_grf)
        rate, lo, hi = wilson(int(self.fell.sum()), len(self.fell))
        return {
            "distance_m": d,
            "distance_ci": dh,
            "peak_grf_bw": g,
            "peak_grf_ci": gh,
            "fall_rate": rate,
            "fall_rate_lo": lo,
            "fall_rate_hi": hi,
        }


def task_runs(
    scene: Scene, backend: str, profile: FidelityProfile, seeds: int, seconds: float
) -> TaskStats:
    """``seeds`` runs of ``seconds`` each of the scene under ``profile``: reset seed s,
    then the fixed excitation pattern; a run stops at a fall or a health failure."""
    env = MuscleEnv(with_profile(scene, backend, profile), backend)
    steps = round(seconds * scene.control_hz)
    pattern = body_excitations(scene.body, env.sim.muscle_names, steps, env.dt, PATTERN_SEED)
    grf = [i for i, n in enumerate(env.obs_names) if n.startswith("grf:")]
    distance, fell, peak, counts, walls = [], [], [], [], []
    health: dict[str, int] = {}
    for seed in range(seeds):
        env.reset(seed=seed)
        top, info, done, k = 0.0, {"distance": 0.0, "health": "ok"}, False, 0
        start = time.perf_counter()
        for k in range(steps):
            obs, _, terminated, _, info = env.step(pattern[k])
            top = max(top, float(obs[grf].sum()) if grf else 0.0)
            if terminated:
                done = True
                break
        wall = time.perf_counter() - start
        if info["health"] != "ok":
            health[info["health"]] = health.get(info["health"], 0) + 1
        distance.append(info["distance"])
        fell.append(done and info["health"] == "ok")
        peak.append(top)
        counts.append(k + 1)
        walls.append(wall)
    return TaskStats(
        np.array(distance),
        np.array(fell),
        np.array(peak),
        np.array(counts),
        np.array(walls),
        env.dt,
        health,
    )


def difference(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Difference of means ``a - b`` with its 95% half-width (Welch, normal approximation)."""
    if len(a) < 2 or len(b) < 2:
        return float(np.mean(a) - np.mean(b)), float("nan")
    half = Z95 * math.sqrt(np.var(a, ddof=1) / len(a) + np.var(b, ddof=1) / len(b))
    return float(np.mean(a) - np.mean(b)), half


def speed_runs(
    scene: Scene, backend: str, profile: FidelityProfile, seeds: int, seconds: float, repeats: int
) -> tuple[TaskStats, float]:
    """``task_runs`` repeated ``repeats`` times (the trajectories are identical, only the
    timing differs): the first batch's statistics and the median env steps/s."""
    batches = [task_runs(scene, backend, profile, seeds, seconds) for _ in range(max(1, repeats))]
    return batches[0], float(np.median([b.steps_per_s for b in batches]))
