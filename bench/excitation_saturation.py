"""How often a joint-target policy's muscles are fully excited: is its gait muscle-limited?

Usage: python bench/excitation_saturation.py CHECKPOINT [--scene run-2d+clock] [--episodes 10]
           [--after-s 5] [--json-out FILE]

Runs the policy's mean action on deterministic episodes (seeds 0..N-1) of a scene with
joint-target actions and records, from ``--after-s`` seconds on (the steady gait, past the
start), every reflex update's excitations [n_muscles] and every action [n_dofs]. Prints, per
muscle, the share of updates at full excitation (> 0.99), and per dof the share of actions at
a bound of the targets' span (< 0.02 or > 0.98). A muscle fully excited can give no more
there; but the reflex layer's gains saturate muscles at any pace (the walker's too), so read
the shares against another policy's, not alone.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluate import fitted_to_scene, resolve_checkpoint
from gaitforge.learner.evaluate_episodes import make_runner, policy_act
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.base import Health
from rich.console import Console
from rich.table import Table

FULL = 0.99
BOUND = 0.02


def record(
    checkpoint: Path, scene_ref: str, episodes: int, after_s: float
) -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """Excitations [n_updates, n_muscles] and actions [n_steps, n_dofs] from ``after_s`` on,
    over ``episodes`` deterministic episodes; the muscle and dof names."""
    policy, meta = load_policy(resolve_checkpoint(checkpoint))
    scene = load_scene(scene_ref)
    if scene.action.kind != "joint_targets":
        raise SystemExit(f"--scene {scene_ref}: {scene.action.kind} actions, not joint_targets")
    policy, _ = fitted_to_scene(policy, meta.obs_names, scene, "mujoco")
    first_step = round(after_s * scene.control_hz)
    excitations: list[np.ndarray] = []
    actions: list[np.ndarray] = []
    with make_runner(policy, scene, "mujoco") as runner:
        env = runner.env
        sim_step_reflex = env.sim.step_reflex
        steps = 0

        def recorded_reflex(reflex, duration: float, updates: int) -> tuple[np.ndarray, Health]:
            def excite(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
                excitation = reflex(q, qd)
                if steps > first_step:
                    excitations.append(excitation.copy())
                return excitation

            return sim_step_reflex(excite, duration, updates)

        env.sim.step_reflex = recorded_reflex
        for episode in range(episodes):
            act = policy_act(policy, "deterministic", episode)
            steps = 0

            def recorded_act(obs: np.ndarray, act=act) -> np.ndarray:
                nonlocal steps
                action = act(obs)
                steps += 1
                if steps > first_step:
                    actions.append(np.clip(action, 0.0, 1.0))
                return action

            runner.run(recorded_act, episode, [])
        return (np.array(excitations), np.array(actions), list(env.sim.muscle_names),
                list(env.sim.dof_names))  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--scene", default="run-2d+clock")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--after-s", type=float, default=5.0)
    parser.add_argument("--json-out", type=Path)
    args = parser.parse_args()
    excitations, actions, muscles, dofs = record(
        args.checkpoint, args.scene, args.episodes, args.after_s
    )
    fully = excitations > FULL
    full, mean = fully.mean(axis=0), excitations.mean(axis=0)
    at_bound = ((actions < BOUND) | (actions > 1 - BOUND)).mean(axis=0)
    table = Table(title=f"{args.checkpoint} on {args.scene}, {args.episodes} deterministic "
                        f"episodes from {args.after_s:g} s ({len(actions)} steps)")  # fmt: skip
    table.add_column("muscle")
    table.add_column("fully excited", justify="right")
    table.add_column("mean excitation", justify="right")
    for name, share, muscle_mean in zip(muscles, full, mean, strict=True):
        table.add_row(name, f"{share:.0%}", f"{muscle_mean:.2f}")
    table.add_row("all", f"{fully.mean():.0%}", f"{excitations.mean():.2f}")
    console = Console(width=120)
    console.print(table)
    console.print("actions at a bound of the span: " + ", ".join(
        f"{d} {s:.0%}" for d, s in zip(dofs, at_bound, strict=True)))  # fmt: skip
    if args.json_out:
        args.json_out.write_text(json.dumps({
            "checkpoint": str(args.checkpoint), "scene": args.scene, "episodes": args.episodes,
            "after_s": args.after_s, "steps": len(actions),
            "fully_excited": dict(zip(muscles, full.round(3).tolist(), strict=True)),
            "mean_excitation": dict(zip(muscles, mean.round(3).tolist(), strict=True)),
            "actions_at_bound": dict(zip(dofs, at_bound.round(3).tolist(), strict=True)),
        }, indent=1))  # fmt: skip


if __name__ == "__main__":
    main()
