"""One policy on both simulators, side by side: deterministic episodes of a scene on MuJoCo
and on OpenSim from the same reset seeds, and where they part: the pelvis's height, forward
distance from the reset and pitch, each foot's normal ground force, each kept joint's angle
and each muscle's activation, against time (the median over the episodes still up). Where the
policy is the same and the body is the same, what differs is the simulators' own modelling
(contact above all: MuJoCo's soft constraints against the reference's Hunt-Crossley spheres).

Usage: python bench/cross_sim.py CHECKPOINT [--scene walk-2d+clock] [--episodes 5]
           [--seed 0] [--every-s 0.2] [--until-s 3] [--out cross-sim.png]
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluation.episodes import make_runner, policy_act
from gaitforge.learner.evaluation.evaluate import resolve_checkpoint
from gaitforge.learner.policy import ActorCritic
from gaitforge.workers.env import GRAVITY
from gaitforge.workers.episode import Observer
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim.pose import pelvis_pitch_list
from rich.console import Console
from rich.table import Table

matplotlib.use("Agg")
import matplotlib.pyplot as plt

console = Console(width=160)
BACKENDS = ("mujoco", "opensim")
SERIES = ("height", "forward", "pitch", "foot_r", "foot_l")
"""pelvis height (m), forward distance from the reset (m), pitch (rad, forward lean > 0),
the right and left foot's normal ground force (body weights); then each kept joint's angle
(``q:NAME``, rad) and each muscle's activation (``a:NAME``, 0-1)"""


class BodyLog(Observer):
    """After each step: the series named in ``names`` (:data:`SERIES`, then ``q:`` each kept
    joint and ``a:`` each muscle), one row per step."""

    def on_reset(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> None:
        self.rows: list[list[float]] = []
        sim = env.sim
        self.names = [
            *SERIES,
            *(f"q:{n}" for n in sim.dof_names),
            *(f"a:{n}" for n in sim.muscle_names),
        ]
        state = env.sim.state()
        self._start = float(state.pelvis_pos[env.sim.forward_axis])
        self._weight = env.sim.report.mass * GRAVITY

    def on_step(
        self,
        env: Any,
        action: np.ndarray,
        obs: np.ndarray,
        reward: float,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> None:
        s, up, fwd = env.sim.state(), env.sim.up_axis, env.sim.forward_axis
        pitch = -pelvis_pitch_list(s.pelvis_up, up, fwd)[0]  # OpenSim's tilt, lean forward > 0
        feet = (s.foot_forces / self._weight).tolist() + [float("nan")] * 2
        self.rows.append(
            [
                float(s.pelvis_pos[up]),
                float(s.pelvis_pos[fwd]) - self._start,
                pitch,
                feet[0],
                feet[1],
                *s.dof_pos.tolist(),
                *s.activations.tolist(),
            ]
        )


def run(
    policy: ActorCritic, scene: Scene, backend: str, episodes: int, seed: int
) -> tuple[np.ndarray, list[str]]:
    """([episodes, steps, series], the series' names), nan after an episode's end."""
    runs, names = [], []
    with make_runner(policy, scene, backend) as runner:
        for i in range(episodes):
            log = BodyLog()
            runner.run(policy_act(policy, "deterministic", seed + i), seed + i, [log])
            runs.append(np.array(log.rows))
            names = log.names
            console.log(f"{backend} episode {i}: {len(log.rows)} steps")
    out = np.full((episodes, scene.steps_per_episode, len(names)), np.nan)
    for i, rows in enumerate(runs):
        out[i, : len(rows)] = rows
    return out, names


def draw_series(
    ax: Any, t: np.ndarray, logs: dict[str, np.ndarray], median: dict[str, np.ndarray], column: int
) -> None:
    """One series on ``ax`` per backend: every episode thin, the median thick."""
    for b, color in zip(BACKENDS, ("tab:blue", "tab:red"), strict=True):
        for episode in logs[b]:
            ax.plot(t, episode[:, column], color=color, alpha=0.3, lw=0.8)
        ax.plot(t, median[b][:, column], color=color, lw=2, label=b)
    ax.grid(alpha=0.3)


def plot_grid(
    t: np.ndarray,
    logs: dict[str, np.ndarray],
    median: dict[str, np.ndarray],
    columns: list[int],
    labels: list[str],
    title: str,
    out: Path,
) -> None:
    """One panel per series column (:func:`draw_series`), three to a row, saved to ``out``."""
    cols = 3
    rows = -(-len(columns) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.4 * rows), sharex=True, squeeze=False)
    for ax, j, label in zip(axes.flat, columns, labels, strict=False):
        draw_series(ax, t, logs, median, j)
        ax.set_title(label, fontsize=9)
    for ax in axes.flat[len(columns) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--scene", default="walk-2d+clock")
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--every-s", type=float, default=0.2, help="table rows every so many s")
    parser.add_argument("--until-s", type=float, default=None, help="table and plot end (s)")
    parser.add_argument("--out", type=Path, default=Path("cross-sim.png"))
    args = parser.parse_args()
    policy, _ = load_policy(resolve_checkpoint(args.checkpoint))
    scene = load_scene(args.scene).resolved()
    dt = 1.0 / scene.control_hz
    runs = {b: run(policy, scene, b, args.episodes, args.seed) for b in BACKENDS}
    logs = {b: v for b, (v, _) in runs.items()}
    names = runs["mujoco"][1]
    if names != runs["opensim"][1]:
        raise SystemExit(f"the simulators name their series differently: {runs['opensim'][1]}")
    with warnings.catch_warnings():  # a time where no episode is up: nan, said by "up" = 0
        warnings.simplefilter("ignore", RuntimeWarning)
        median = {b: np.nanmedian(v, axis=0) for b, v in logs.items()}
    steps = scene.steps_per_episode
    if args.until_s is not None:
        steps = min(steps, max(1, round(args.until_s / dt)))
    up = {b: np.isfinite(v[:, :, 0]).sum(axis=0) for b, v in logs.items()}
    table = Table(title=f"{args.checkpoint} on {scene.name}: median over the episodes still up")
    table.add_column("t s", justify="right")
    for b in BACKENDS:
        for name in ("up", "height m", "forward m", "pitch rad", "feet r/l BW"):
            table.add_column(f"{b[:2]} {name}", justify="right")
    every = max(1, round(args.every_s / dt))
    for k in range(every - 1, steps, every):
        cells = [f"{(k + 1) * dt:.2f}"]
        for b in BACKENDS:
            h, x, p, fr, fl = median[b][k][: len(SERIES)]
            cells += [str(up[b][k]), f"{h:.3f}", f"{x:+.2f}", f"{p:+.2f}", f"{fr:.2f}/{fl:.2f}"]
        table.add_row(*cells)
    console.print(table)
    joints = [j for j, n in enumerate(names) if n.startswith("q:")]
    angles = Table(title="joint angles, degrees, median over the episodes up: MuJoCo / OpenSim")
    angles.add_column("t s", justify="right")
    for j in joints:
        angles.add_column(names[j][2:], justify="right")
    for k in range(every - 1, steps, every):
        deg = {b: np.degrees(median[b][k]) for b in BACKENDS}
        pairs = [f"{deg['mujoco'][j]:+.0f}/{deg['opensim'][j]:+.0f}" for j in joints]
        angles.add_row(f"{(k + 1) * dt:.2f}", *pairs)
    console.print(angles)
    t = (np.arange(scene.steps_per_episode) + 1) * dt
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    labels = ("pelvis height m", "forward m", "pitch rad")
    for j, (ax, label) in enumerate(zip(axes, labels, strict=True)):
        draw_series(ax, t, logs, median, j)
        ax.set_ylabel(label)
    axes[0].legend()
    axes[-1].set_xlabel("time from the reset, s")
    axes[-1].set_xlim(0, steps * dt)
    title = f"{args.checkpoint.name} on {scene.name}, {args.episodes} deterministic episodes"
    fig.suptitle(title)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    for part, prefix, unit in (("joints", "q:", "rad"), ("muscles", "a:", "activation")):
        columns = [j for j, n in enumerate(names) if n.startswith(prefix)]
        plot_grid(
            t[:steps],
            {b: v[:, :steps] for b, v in logs.items()},
            {b: v[:steps] for b, v in median.items()},
            columns,
            [f"{names[j][2:]} {unit}" for j in columns],
            title,
            args.out.with_name(f"{args.out.stem}-{part}.png"),
        )
    data = {
        b: {
            "series": names,
            "dt_s": dt,
            "episodes_up": up[b].tolist(),
            "median": np.where(np.isfinite(median[b]), median[b].round(4), None).tolist(),
        }
        for b in BACKENDS
    }
    args.out.with_suffix(".json").write_text(json.dumps(data))
    console.log(f"wrote {args.out} (and -joints, -muscles) and {args.out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
