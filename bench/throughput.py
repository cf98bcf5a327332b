"""Env steps/s of the rollout pool for 1..N actors against one process, and RLlib's env runners.

Usage: python bench/throughput.py --scene walk-2d [--backend mujoco|opensim] [--max-actors N]
       [--seconds S] [--envs-per-worker K] [--fragment-length T] [--rllib]

Rows, measured one after the other in one run:
* raw: one MuscleEnv in this process stepping uniform random excitations (numpy, no
  policy: the env alone), resets included, for S seconds, once first and once last (mean
  reported); the pool's rows also pay for their policy (batched over K envs), fragment
  assembly and transport, which is what the efficiency measures;
* pool n: a WorkerPool of n actors (n = 1..N, N the CPU count; ``ray.init(num_cpus=N)``)
  with K envs each and T-step fragments;
* rllib (``--rllib``): RLlib's PPO env runners (new API stack), N of them with K envs each,
  random actions (no module forward pass, as the pool's policy is near-free), each always
  with one ``sample(num_timesteps=T*K)`` request in flight, episodes returned to the driver.

Start-up is excluded: fragments are discarded until every actor has delivered one. Then for
S seconds each actor's rate is the env steps of the fragments it delivered over the time
from its last discarded fragment to its last delivered one (no partial fragment at either
edge of the window); a row is the sum over its actors. Efficiency = steps/s / (actors x raw).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import logging
import os
import platform
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np
import ray
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import WorkerPool
from gaitforge.workers.scenes import load_scene
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

console = Console()
POLL_S = 0.5
STARTUP_LIMIT_S = 600.0
RLLIB_ENV = "gaitforge-muscle"
RLLIB_MISSING = (
    "--rllib needs RLlib's dependencies: pip install 'gaitforge[bench]' (ray[rllib]==2.60.0)"
)


class Meter:
    """Per-actor clocks: an actor's rate is the steps it delivered after its reference
    arrival over the time from that arrival to its last one."""

    def __init__(self) -> None:
        self.ref: dict[int, float] = {}
        self.last: dict[int, float] = {}
        self.steps: Counter[int] = Counter()

    def reference(self, actor: int) -> None:
        self.ref[actor] = self.last[actor] = time.perf_counter()

    def add(self, actor: int, steps: int) -> None:
        self.steps[actor] += steps
        self.last[actor] = time.perf_counter()

    def rate(self) -> float:
        idle = [a for a in self.ref if not self.steps[a]]
        if idle:
            console.print(f"[yellow]actors {idle} delivered nothing in the window: raise --seconds")
        return sum(self.steps[a] / (self.last[a] - self.ref[a]) for a in self.ref if self.steps[a])


def measure(
    label: str,
    actors: int,
    poll: Callable[[float], Iterable[tuple[int, int]]],
    seconds: float,
    progress: Progress,
) -> float:
    """Drive ``poll(timeout) -> [(actor, steps), ...]``: warm up, then meter S seconds."""
    task = progress.add_task(f"{label}: starting", total=seconds)
    meter = Meter()
    deadline = time.perf_counter() + STARTUP_LIMIT_S
    while len(meter.ref) < actors:  # start-up: discard until every actor has delivered
        if time.perf_counter() > deadline:
            raise TimeoutError(f"only {len(meter.ref)} of {actors} actors started")
        for actor, _ in poll(POLL_S):
            meter.reference(actor)
    progress.update(task, description=f"{label}: running")
    start = time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        progress.update(task, completed=elapsed)
        for actor, steps in poll(min(POLL_S, seconds - elapsed)):
            meter.add(actor, steps)
    progress.update(task, completed=seconds)
    return meter.rate()


def raw_rate(scene_name: str, backend: str, seconds: float, progress: Progress) -> float:
    """One env in this process, uniform random excitations drawn with numpy (no policy, no
    torch: the env alone); resets included."""
    env = MuscleEnv(scene_name, backend)
    rng = np.random.default_rng(0)
    task = progress.add_task("raw: running", total=seconds)
    env.reset(seed=0)
    steps, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        _, _, terminated, truncated, _ = env.step(rng.uniform(0.0, 1.0, env.action_space.shape))
        steps += 1
        if terminated or truncated:
            env.reset()
        if steps % 20 == 0:
            progress.update(task, completed=elapsed)
    progress.update(task, completed=seconds)
    return steps / (time.perf_counter() - start)


def pool_rate(
    args: argparse.Namespace,
    actors: int,
    act_dim: int,
    progress: Progress,
    inspect: Callable[[WorkerPool], None] | None = None,
) -> float:
    """Env steps/s of a pool of ``actors`` actors; ``inspect`` sees the pool after the
    measurement, before it closes (e.g. which nodes its actors ran on)."""
    pool = WorkerPool(
        load_scene(args.scene).resolved(),
        functools.partial(UniformExcitationPolicy, act_dim),
        backend=args.backend,
        num_workers=actors,
        envs_per_worker=args.envs_per_worker,
        fragment_length=args.fragment_length,
    )

    def poll(timeout: float) -> list[tuple[int, int]]:
        try:
            fragment, _ = pool.next_fragment(timeout_s=timeout)
        except TimeoutError:
            return []
        return [(fragment.worker, fragment.steps)]

    try:
        rate = measure(f"pool {actors} actors", actors, poll, args.seconds, progress)
        if inspect is not None:
            inspect(pool)
        return rate
    finally:
        pool.close()


def rllib_rate(args: argparse.Namespace, runners: int, progress: Progress) -> float:
    """RLlib's env runners (PPO, new API stack), each always with one request in flight."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner
    from ray.tune.registry import register_env

    logging.getLogger("ray.rllib").setLevel(logging.ERROR)  # new-API-stack notices
    register_env(RLLIB_ENV, lambda cfg: MuscleEnv(cfg["scene"], cfg["backend"]))
    config = (
        PPOConfig()
        .environment(RLLIB_ENV, env_config={"scene": args.scene, "backend": args.backend})
        .env_runners(
            num_env_runners=runners,
            num_envs_per_env_runner=args.envs_per_worker,
            rollout_fragment_length=args.fragment_length,
        )
    )
    algo = config.build_algo()
    group = algo.env_runner_group
    timesteps = args.fragment_length * args.envs_per_worker

    def sample(runner: SingleAgentEnvRunner) -> list:  # runs on the env runner
        return runner.sample(num_timesteps=timesteps, random_actions=True)

    def poll(timeout: float) -> list[tuple[int, int]]:
        ready = group.fetch_ready_async_reqs(tags=RLLIB_ENV, timeout_seconds=timeout)
        for runner_id, _ in ready:
            group.foreach_env_runner_async(sample, RLLIB_ENV, remote_worker_ids=[runner_id])
        return [(rid, sum(len(e) for e in episodes)) for rid, episodes in ready]

    try:
        group.foreach_env_runner_async(sample, RLLIB_ENV)
        return measure(f"rllib {runners} runners", runners, poll, args.seconds, progress)
    finally:
        algo.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="walk-2d")
    parser.add_argument("--backend", default="mujoco", choices=["mujoco", "opensim"])
    parser.add_argument("--max-actors", type=int, help="default: the CPU count")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--envs-per-worker", type=int, default=4)
    parser.add_argument("--fragment-length", type=int, default=256)
    parser.add_argument("--rllib", action="store_true", help="add RLlib's env runners")
    args = parser.parse_args()
    if args.rllib:
        try:
            importlib.import_module("ray.rllib.algorithms.ppo")
        except ImportError:
            sys.exit(RLLIB_MISSING)
    n = args.max_actors or os.cpu_count() or 1
    console.print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; "
        f"python {platform.python_version()}, ray {ray.__version__}, "
        f"mujoco {mujoco.__version__}\nplatform: {platform.platform()}"
    )
    act_dim = MuscleEnv(args.scene, args.backend).action_space.shape[0]
    rows: list[tuple[str, int, float]] = []
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        raws = [raw_rate(args.scene, args.backend, args.seconds, progress)]
        ray.init(
            address="local",
            num_cpus=n,
            include_dashboard=False,
            logging_level=logging.ERROR,
            log_to_driver=False,
        )
        try:
            for actors in range(1, n + 1):
                rows.append(("pool", actors, pool_rate(args, actors, act_dim, progress)))
            if args.rllib:
                rows.append(("rllib env runners", n, rllib_rate(args, n, progress)))
        finally:
            ray.shutdown()
        time.sleep(2.0)  # let Ray's processes exit before the last raw run
        raws.append(raw_rate(args.scene, args.backend, args.seconds, progress))
    raw = sum(raws) / 2
    table = Table(
        "row",
        "actors",
        "env steps/s",
        "efficiency",
        title=f"{args.scene} on {args.backend}: env steps/s",
        caption=f"{args.seconds:g} s per row, {args.envs_per_worker} envs per actor, "
        f"{args.fragment_length}-step fragments; raw = mean of {raws[0]:.1f} (first) "
        f"and {raws[1]:.1f} (last)",
    )
    table.add_row("raw, one process", "1", f"{raw:.1f}", "1.00")
    for label, actors, rate in rows:
        table.add_row(label, str(actors), f"{rate:.1f}", f"{rate / (actors * raw):.2f}")
    console.print(table)


if __name__ == "__main__":
    main()
