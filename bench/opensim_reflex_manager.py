"""OpenSim's reflex layer with one Manager a control step against a new Manager per update.

Usage: python bench/opensim_reflex_manager.py [--seconds S] [--repeats R] [--scene SCENE]

A joint-target control step on OpenSim is 20 reflex updates (500 Hz at 25 Hz control). The
simulator integrates them with one ``Manager`` a control step (``OpenSimSimulator.
step_reflex``); before, each update made its own, and ``Manager.initialize`` took about as
long as the integration. For each OpenSim profile (the fixed-step one the fidelity sweep
recommends for walk-2d, ``default`` and ``challenge2017``) this runs both ways on the same
scene, interleaved R times for S seconds each under random joint targets (resets included),
and reports the median env steps/s and their ratio, measured in the same run. Then how far
each way is, after 3 control steps from seed 0, from a converged reference (Runge-Kutta-
Merson at accuracy 1e-8, a new Manager per update): the largest difference over OpenSim's
state vector (rad, m, rad/s, m/s, activations and fibre lengths alike; the fixed 1-ms step is
far from converged under random targets, and the same for both ways, bit for bit).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim.base import Health, Reflex
from rich.console import Console
from rich.table import Table

PROFILES = {
    "semi-explicit Euler, fixed 1 ms": FidelityProfile(
        integrator="semi-explicit-euler2", timestep=0.001, fixed_step=True
    ),
    "default": "default",
    "challenge2017": "challenge2017",
}
REFERENCE = FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=1e-8)


def on_opensim(scene: Scene, profile: FidelityProfile | str) -> Scene:
    return scene.model_copy(update={"fidelity": {"opensim": profile}, "backends": ["opensim"]})


def new_manager_per_update(env: MuscleEnv) -> None:
    """Make ``env``'s simulator integrate each reflex update with its own Manager (one
    ``step_reflex`` of a single update each), as before."""
    one_manager_a_step = env.sim.step_reflex

    def step_reflex(reflex: Reflex, duration: float, updates: int) -> tuple[np.ndarray, Health]:
        total, done = 0.0, 0
        for done in range(1, updates + 1):  # noqa: B007
            excitation, health = one_manager_a_step(reflex, duration / updates, 1)
            total = total + excitation
            if not health.ok:
                break
        return total / done, health

    env.sim.step_reflex = step_reflex


def steps_per_s(env: MuscleEnv, seconds: float, seed: int) -> float:
    """Env steps/s under uniform random actions for ``seconds`` of wall clock."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        _, _, terminated, truncated, _ = env.step(rng.uniform(0, 1, env.action_space.shape))
        steps += 1
        if terminated or truncated:
            env.reset(seed=seed + steps)
    return steps / (time.perf_counter() - start)


def state_after(env: MuscleEnv, steps: int = 3) -> np.ndarray:
    """OpenSim's state vector after ``steps`` control steps from seed 0 (actions seed 0)."""
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(steps):
        env.step(rng.uniform(0, 1, env.action_space.shape))
    return env.sim.osim_state.getY().to_numpy().copy()


def make_env(scene: Scene, profile: FidelityProfile | str, old: bool) -> MuscleEnv:
    env = MuscleEnv(on_opensim(scene, profile), "opensim")
    if old:
        new_manager_per_update(env)
    return env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scene", default="walk-2d+clock")
    args = parser.parse_args()
    scene = load_scene(args.scene)
    reference = state_after(make_env(scene, REFERENCE, old=True))
    table = Table(title=f"{args.scene} on OpenSim, reflex updates: one Manager a control step "
                        "against one per update")  # fmt: skip
    columns = ("profile", "per update, steps/s", "a control step, steps/s", "ratio",
               "per update, off the reference", "a control step, off the reference")  # fmt: skip
    for column in columns:
        table.add_column(column, justify="left" if column == "profile" else "right")
    for label, profile in PROFILES.items():
        envs = {old: make_env(scene, profile, old) for old in (True, False)}
        rates: dict[bool, list[float]] = {True: [], False: []}
        for repeat in range(args.repeats):
            for old, env in envs.items():
                rates[old].append(steps_per_s(env, args.seconds, seed=repeat))
        old_rate, new_rate = (statistics.median(rates[old]) for old in (True, False))
        errors = {old: np.abs(state_after(env) - reference).max() for old, env in envs.items()}
        table.add_row(label, f"{old_rate:.1f}", f"{new_rate:.1f}", f"{new_rate / old_rate:.2f}",
                      f"{errors[True]:.1e}", f"{errors[False]:.1e}")  # fmt: skip
    Console(width=150).print(table)


if __name__ == "__main__":
    main()
