"""Distil a searched start (``bench/start_search.py``'s offsets) into the policy's network, so
that a plain checkpoint starts as policy + offsets does: DAgger (Ross et al. 2011). Round 0
rolls out the teacher (the policy with the offsets), later rounds the student; every visited
observation is labelled with the teacher's action there (the policy's mean plus the offsets
at that time, legs swapped in a mirrored episode, clipped to [0, 1]; the policy's own after
the last knot), and the student (the policy to start with) is regressed on all labels so far
(``learner.distil.fit_student``, the actor only). Then the policy, the teacher and the
student are judged on the same fresh deterministic episodes (seeds from 10000), and the
student is written as a checkpoint (``gaitforge evaluate OUT/student`` runs it).

Usage: python bench/start_distil.py SEARCH_DIR --out DIR [--rounds 4] [--episodes 32]
           [--epochs 20] [--lr 3e-4] [--judge 200] [--processes 2]
"""

from __future__ import annotations

import argparse
import copy
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np
import torch
from gaitforge.learner.checkpoint import save_checkpoint
from gaitforge.learner.distil import fit_student
from gaitforge.learner.policy import ActorCritic
from gaitforge.workers.episode import EpisodeRunner
from rich.console import Console

sys.path.insert(0, str(Path(__file__).parent))
from start_offsets import (
    StartOffsets,
    judge_episode,
    mirrored_order,
    open_runner,
    open_worker,
    plot_speeds,
    summary,
    summary_table,
    with_offsets,
)

console = Console(width=160)


def mean_action(policy: ActorCritic, obs: np.ndarray) -> np.ndarray:
    """The policy's deterministic action [n_act] for one observation [n_obs]."""
    with torch.inference_mode():
        x = torch.as_tensor(obs, dtype=torch.float32)[None]
        return policy.mean_action(x)[0].numpy().astype(np.float64)


def collect(
    runner: EpisodeRunner,
    teacher: ActorCritic,
    student: ActorCritic,
    offsets: StartOffsets,
    seeds: range,
    student_acts: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Observations [N, n_obs] and the teacher's actions there [N, n_act] (float32) over
    deterministic episodes of ``seeds``, the student acting if ``student_acts`` else the
    teacher."""
    observations, labels = [], []

    def record(obs: np.ndarray) -> np.ndarray:
        observations.append(np.array(obs, dtype=np.float32))
        return mean_action(teacher, obs)

    for seed in seeds:
        label = with_offsets(record, offsets, runner)  # the teacher, recording what it sees

        def act(obs: np.ndarray, label=label) -> np.ndarray:
            labels.append(label(obs).astype(np.float32))
            return mean_action(student, obs) if student_acts else labels[-1].astype(np.float64)

        runner.run(act, seed)
    return np.stack(observations), np.stack(labels)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("search", type=Path, help="a start_search.py --out directory")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--episodes", type=int, default=32, help="per round; seeds from 2000")
    parser.add_argument("--epochs", type=int, default=20)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--judge", type=int, default=200, help="episodes; seeds from 10000")
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    found = json.loads((args.search / "start-search.json").read_text())
    checkpoint, scene_ref = found["args"]["checkpoint"], found["args"]["scene"]
    if found["args"].get("range_rad") is not None:
        raise SystemExit(
            f"{args.search}: searched with --range-rad, which a network of the "
            "scene cannot act out; distil a search at the scene's own range"
        )
    knots = tuple(found["knots_s"])
    teacher, runner, meta = open_runner(checkpoint, scene_ref)
    scene = runner.scene
    offsets = StartOffsets(knots, np.array(found["offsets"]), mirrored_order(runner.act_names))
    student = copy.deepcopy(teacher)
    obs_all, labels_all, started = [], [], time.monotonic()
    with runner:
        for round_ in range(args.rounds):
            seeds = range(2000 + round_ * args.episodes, 2000 + (round_ + 1) * args.episodes)
            obs, labels = collect(runner, teacher, student, offsets, seeds, round_ > 0)
            obs_all.append(obs)
            labels_all.append(labels)
            with torch.inference_mode():
                off = student.mean_action(torch.as_tensor(obs)) - torch.as_tensor(labels)
            losses = fit_student(
                student,
                torch.as_tensor(np.concatenate(obs_all)),
                None,
                torch.as_tensor(np.concatenate(labels_all)),
                epochs=args.epochs,
                lr=args.lr,
                seed=round_,
            )
            console.log(
                f"round {round_}: {len(obs)} steps, {'student' if round_ else 'teacher'} acting; "
                f"the student's squared error there {float(off.pow(2).mean()):.5f}, after "
                f"fitting all {sum(map(len, obs_all))}: {losses['action_mse']:.5f}; "
                f"{time.monotonic() - started:.0f} s"
            )
    provenance = {
        "command": " ".join(sys.argv),
        "distilled_from": checkpoint,
        "search": str(args.search),
        "scene": scene_ref,
    }
    student_dir = save_checkpoint(
        args.out / "student",
        meta.env_steps,
        student.state_dict(),
        meta.model_copy(
            update={
                "provenance": provenance,
                "network": student.describe(),
                "obs_names": list(runner.obs_names),
            }
        ),
    )
    judge_seeds = range(10000, 10000 + args.judge)
    arms = {
        "policy": (checkpoint, None),
        "teacher (policy + offsets)": (checkpoint, offsets.values),
        "student (distilled)": (str(student_dir), None),
    }
    judged = {}
    for label, (path, values) in arms.items():
        context = mp.get_context("spawn")
        with context.Pool(args.processes, open_worker, (path, scene_ref, knots)) as pool:
            judged[label] = pool.map(judge_episode, [(values, s) for s in judge_seeds])
        console.log(f"{label}: judged")
    summaries = {k: summary(runs, scene.control_hz, scene.episode_s) for k, runs in judged.items()}
    console.print(
        summary_table(f"{scene_ref}: {args.judge} deterministic episodes (seeds 10000-)", summaries)
    )
    (args.out / "start-distil.json").write_text(
        json.dumps(
            {
                "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
                "student": str(student_dir),
                "summaries": summaries,
            },
            indent=1,
        )
    )
    plot_speeds(
        judged,
        scene.control_hz,
        f"{scene_ref}: the searched start distilled",
        args.out / "start-distil.png",
    )


if __name__ == "__main__":
    main()
