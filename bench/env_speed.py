"""Env steps/s on one core for every catalogue scene and backend, and what pruning saves.

Usage: python bench/env_speed.py [--seconds S] [--repeats R] [--no-opensim]
                                 [--only env|actions|pruning]

Table 1: each scene on MuJoCo at its profile and, for scenes that name OpenSim, on OpenSim
at the ``default`` profile and at the 2017 challenge's setting (Runge-Kutta-Merson,
accuracy 5e-5): random excitations for S wall-clock seconds, R repeats interleaved, median
reported, resets included. The ratio column is the row's speed over the same scene on
MuJoCo, measured in the same run.

Table 2: joint-target actions (``action.kind: joint_targets``, the reflex layer) against
excitations on the same scenes at the same control rate, random actions, R repeats
interleaved (the ratio is the one to read: the layer updates the excitations 500 times a
second, each update a separate simulator call).

Table 3: the raw ``mj_step`` rate of the pruned ``walk-3d`` model against MyoLeg as shipped
(nothing removed), alternated in one run so that machine noise hits both alike; each restarts
standing whenever it falls, as training episodes do.
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
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.probe import ProbeResult, random_excitations
from gaitforge.workers.scenes import Scene, catalogue, load_scene
from gaitforge.workers.sim.mujoco.compile import INTEGRATORS, source_spec
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator
from rich.console import Console
from rich.table import Table

console = Console()
OPENSIM_PROFILES = ("default", "challenge2017")


def median_run(env: MuscleEnv, seconds: float, repeats: int) -> ProbeResult:
    runs = [random_excitations(env, seconds, seed=r) for r in range(repeats)]
    return sorted(runs, key=lambda r: r.steps_per_s)[len(runs) // 2]


def physics_steps_per_s(model: mujoco.MjModel, seconds: float, seed: int = 0) -> float:
    """Raw mj_step rate under uniform random controls held for 10 ms each, restarting from
    the standing keyframe when the pelvis drops below 0.6 m, as a training episode would
    (a body lying on the floor is not what training simulates)."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    n_sub = max(1, round(0.01 / model.opt.timestep))
    pelvis = model.body("pelvis").id
    steps = 0
    start = time.perf_counter()
    mujoco.mj_resetDataKeyframe(model, data, 0)
    while time.perf_counter() - start < seconds:
        data.ctrl[:] = rng.uniform(0, 1, model.nu)
        mujoco.mj_step(model, data, nstep=n_sub)
        steps += n_sub
        if data.xpos[pelvis, 2] < 0.6 or data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            mujoco.mj_resetDataKeyframe(model, data, 0)
    return steps / (time.perf_counter() - start)


def env_table(seconds: float, repeats: int, opensim: bool) -> Table:
    table = Table(
        "scene",
        "backend",
        "profile",
        "dofs",
        "muscles",
        "env steps/s",
        "real-time x",
        "vs MuJoCo",
        title="Env steps/s, one core (median)",
    )
    for name in catalogue():
        scene = load_scene(name)
        runs: list[tuple[str, str, MuscleEnv]] = [("mujoco", "default", MuscleEnv(scene))]
        if opensim and "opensim" in scene.backends:
            runs += [
                ("opensim", p, MuscleEnv(_with_profile(scene, p), "opensim"))
                for p in OPENSIM_PROFILES
            ]
        base = None
        for backend, profile, env in runs:
            result = median_run(env, seconds, repeats)
            base = base or result.steps_per_s
            size = env.sim.report.size
            table.add_row(
                name,
                backend,
                profile,
                str(size["dofs"]),
                str(size["muscles"]),
                f"{result.steps_per_s:.1f}",
                f"{result.realtime_factor:.2f}",
                f"{result.steps_per_s / base:.4f}",
            )
    return table


ACTION_SCENES = ("walk-2d", "imitate-walk-2d")


def action_table(seconds: float, repeats: int, opensim: bool) -> Table:
    table = Table(
        "scene",
        "backend",
        "control Hz",
        "action",
        "entries",
        "env steps/s",
        "vs excitations",
        title="Joint targets against excitations, one core (median)",
    )
    for name in ACTION_SCENES:
        scene = load_scene(name).model_copy(update={"control_hz": 25.0})
        targets = Scene.model_validate({**scene.model_dump(), "action": {"kind": "joint_targets"}})
        for backend in ("mujoco", "opensim") if opensim else ("mujoco",):
            envs = {
                "excitations": MuscleEnv(scene, backend),
                "joint targets": MuscleEnv(targets, backend),
            }
            rates: dict[str, list[float]] = {k: [] for k in envs}
            for r in range(repeats):
                for kind, env in envs.items():
                    rates[kind].append(random_excitations(env, seconds, seed=r).steps_per_s)
            base = statistics.median(rates["excitations"])
            for kind, env in envs.items():
                rate = statistics.median(rates[kind])
                table.add_row(
                    name,
                    backend,
                    "25",
                    kind,
                    str(env.action_space.shape[0]),
                    f"{rate:.1f}",
                    f"{rate / base:.2f}",
                )
    return table


def _with_profile(scene: Scene, profile: str) -> Scene:
    return scene.model_copy(update={"fidelity": {"mujoco": "default", "opensim": profile}})


def pruning_table(seconds: float, repeats: int) -> Table:
    walk = load_scene("walk-3d")
    profile = walk.profile("mujoco")
    full_spec = source_spec("myoleg")
    full_spec.option.integrator = INTEGRATORS[profile.integrator]
    full_spec.option.timestep = profile.timestep
    sim = MujocoSimulator(walk)
    models = {
        "MyoLeg as shipped": (full_spec.compile(), sim.report.size_full),
        "walk-3d pruned": (sim.model, sim.report.size),
    }
    rates: dict[str, list[float]] = {label: [] for label in models}
    for r in range(repeats):
        for label, (model, _) in models.items():
            rates[label].append(physics_steps_per_s(model, seconds, r))
    table = Table(
        "model",
        "dofs",
        "muscles",
        "contact pairs",
        "geoms",
        "sites",
        "physics steps/s",
        "ratio",
        title=f"Pruning: raw mj_step rate ({profile.integrator}, {profile.timestep * 1000:g} ms)",
    )
    base = statistics.median(rates["MyoLeg as shipped"])
    for label, (_, size) in models.items():
        rate = statistics.median(rates[label])
        table.add_row(
            label,
            *(str(size[k]) for k in ("dofs", "muscles", "contact_pairs", "geoms", "sites")),
            f"{rate:.0f}",
            f"{rate / base:.2f}",
        )
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-opensim", action="store_true")
    parser.add_argument(
        "--only", choices=["env", "actions", "pruning"], help="print one table only"
    )
    args = parser.parse_args()
    console.print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, mujoco {mujoco.__version__}"
    )
    if args.only in (None, "env"):
        console.print(env_table(args.seconds, args.repeats, not args.no_opensim))
    if args.only in (None, "actions"):
        console.print(action_table(args.seconds, args.repeats, not args.no_opensim))
    if args.only in (None, "pruning"):
        console.print(pruning_table(args.seconds, args.repeats))


if __name__ == "__main__":
    main()
