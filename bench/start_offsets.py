"""Start offsets: an open-loop correction added to a policy's joint-target actions over the
first seconds from standing, and what ``bench/start_search.py`` (which finds them) and
``bench/start_distil.py`` (which puts them into the network) share: the offsets in time,
episodes run with them in a process pool, and the figures they are judged by.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluate import fitted_to_scene, resolve_checkpoint
from gaitforge.learner.evaluate_episodes import make_runner, policy_act
from gaitforge.workers.episode import EpisodeRunner, Observer
from gaitforge.workers.scenes import load_scene
from rich.table import Table

MIRROR_OBS = "phase_mirror"
"""the observation entry that is +1 in a mirrored episode (left and right legs swapped)"""


def mirrored_order(names: list[str]) -> list[int]:
    """For each action entry of ``names``, the index of its other leg's entry (``_r`` <->
    ``_l``); an entry of neither leg maps to itself."""

    def other(name: str) -> str:
        return name[:-2] + {"_r": "_l", "_l": "_r"}.get(name[-2:], name[-2:])

    return [names.index(other(n)) if other(n) in names else i for i, n in enumerate(names)]


@dataclass(frozen=True)
class StartOffsets:
    """Offsets to the actions (action units, [0, 1] scale) in time from the reset.

    ``values`` [n_knots - 1, n_act] are the offsets at ``knots_s`` (s, ascending, the first
    0) but the last, where they are back to 0; linear between knots, 0 after the last. A
    mirrored episode gets the same offsets with the legs swapped (``swap``, from
    :func:`mirrored_order`), so the offsets follow the leg that leads.
    """

    knots_s: tuple[float, ...]
    values: np.ndarray
    swap: list[int]

    def __post_init__(self) -> None:
        if self.values.shape != (len(self.knots_s) - 1, len(self.swap)):
            raise ValueError(
                f"offsets {self.values.shape}: expected ({len(self.knots_s) - 1}, {len(self.swap)})"
            )

    def at(self, t_s: float, mirrored: bool) -> np.ndarray:
        """The offsets [n_act] at ``t_s`` s from the reset."""
        knots = np.vstack([self.values, np.zeros((1, self.values.shape[1]))])
        offsets = np.array(
            [np.interp(t_s, self.knots_s, knots[:, j]) for j in range(knots.shape[1])]
        )
        return offsets[self.swap] if mirrored else offsets


def with_offsets(
    act: Callable[[np.ndarray], np.ndarray], offsets: StartOffsets | None, runner: EpisodeRunner
) -> Callable[[np.ndarray], np.ndarray]:
    """One episode's actions: ``act``'s plus ``offsets`` at the step's time, clipped to [0, 1]
    (``act`` itself without offsets). Counts its calls, so make one per episode."""
    if offsets is None:
        return act
    mirror = runner.obs_names.index(MIRROR_OBS)
    dt = 1.0 / runner.scene.control_hz
    step = 0

    def corrected(obs: np.ndarray) -> np.ndarray:
        nonlocal step
        action = np.clip(act(obs) + offsets.at(step * dt, obs[mirror] > 0), 0.0, 1.0)
        step += 1
        return action

    return corrected


class Distances(Observer):
    """The pelvis's forward distance from the reset (m) after each step."""

    def on_reset(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> None:
        self.distance = [0.0]

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
        self.distance.append(float(info["distance"]))


def open_runner(
    checkpoint: str | Path, scene_ref: str, range_rad: float | None = None
) -> tuple[Any, EpisodeRunner, Any]:
    """The checkpoint's policy fitted to the scene (as ``gaitforge evaluate`` fits it), a
    runner of the scene on MuJoCo, and the checkpoint's meta; with ``range_rad``, the scene's
    joint targets span that (rad) either side of their base instead (see
    :func:`same_targets`)."""
    policy, meta = load_policy(resolve_checkpoint(Path(checkpoint)))
    scene = load_scene(scene_ref).resolved()
    policy, _ = fitted_to_scene(policy, meta.obs_names, scene, "mujoco")
    if range_rad is not None:
        action = scene.action.model_copy(update={"range_rad": range_rad})
        scene = scene.model_copy(update={"action": action})
    return policy, make_runner(policy, scene, "mujoco"), meta


def same_targets(act: Callable[[np.ndarray], np.ndarray], scale: float) -> Callable:
    """``act``'s actions for a scene whose targets span ``1 / scale`` times as far: ``0.5 +
    (a - 0.5) scale``, the same target angles (so offsets may reach further than the policy's
    own range, and the policy acts as it was trained)."""
    if scale == 1.0:
        return act
    return lambda obs: 0.5 + (act(obs) - 0.5) * scale


_worker: dict[str, Any] = {}
"""a pool process's policy, runner, knots, leg swap and action scale (:func:`open_worker`)"""


def open_worker(
    checkpoint: str, scene_ref: str, knots_s: tuple[float, ...], range_rad: float | None = None
) -> None:
    """A pool's initializer: this process's policy and runner, and the knots; with
    ``range_rad``, the targets' span changed and the policy's actions rescaled to it."""
    policy, runner, _ = open_runner(checkpoint, scene_ref, range_rad)
    native = load_scene(scene_ref).resolved().action.range_rad
    _worker.update(
        policy=policy,
        runner=runner,
        knots_s=knots_s,
        swap=mirrored_order(runner.act_names),
        scale=1.0 if range_rad is None else native / range_rad,
    )


def worker_episode(
    values: np.ndarray | None, seed: int, max_s: float | None = None
) -> tuple[list[float], bool]:
    """In a pool process: one deterministic episode of seed ``seed`` with offsets ``values``
    (flat or [n_knots - 1, n_act]; None: the policy alone), for at most ``max_s`` s: the
    distances after each step (m) and whether it fell (the env ended it: the episode
    summary's ``terminated``)."""
    runner: EpisodeRunner = _worker["runner"]
    offsets = None
    if values is not None:
        swap = _worker["swap"]
        offsets = StartOffsets(_worker["knots_s"], np.asarray(values).reshape(-1, len(swap)), swap)
    policy = same_targets(policy_act(_worker["policy"], "deterministic", seed), _worker["scale"])
    act = with_offsets(policy, offsets, runner)
    log = Distances()
    max_steps = None if max_s is None else round(max_s * runner.scene.control_hz)
    ended = runner.run(act, seed, [log], max_steps)
    return log.distance, ended.terminated


def worker_control_hz() -> float:
    """In a pool process: the scene's control steps a second."""
    return float(_worker["runner"].scene.control_hz)


def distance_by(distance: list[float], t_s: float, hz: float) -> float:
    """The distance (m) ``t_s`` s from the reset, from distances after each step at ``hz``
    steps a second (the last, after a fall before then)."""
    return distance[min(len(distance) - 1, round(t_s * hz))]


def judge_episode(args: tuple[np.ndarray | None, int]) -> tuple[list[float], bool]:
    """:func:`worker_episode` for ``Pool.map``: (offsets, seed), the whole episode."""
    return worker_episode(*args)


def summary(runs: list[tuple[list[float], bool]], hz: float, episode_s: float) -> dict[str, float]:
    """Of whole episodes (distances after each step, fell) at ``hz`` control steps a second:
    falls, the mean speed (each episode's distance over its own length, as ``gaitforge
    evaluate`` reports it; m/s), the survivors' mean speed over ``episode_s``, and the median
    distance (m) at 1.2, 2 and 4 s (a fallen episode's last distance after its fall)."""

    def at(t: float) -> float:
        return float(np.median([distance_by(d, t, hz) for d, _ in runs]))

    survivors = [d[-1] / episode_s for d, fell in runs if not fell]
    return {
        "episodes": len(runs),
        "fall_rate": sum(fell for _, fell in runs) / len(runs),
        "mean_speed": float(np.mean([d[-1] * hz / max(1, len(d) - 1) for d, _ in runs])),
        "survivor_speed": float(np.mean(survivors)) if survivors else float("nan"),
        "distance_1.2s": at(1.2),
        "distance_2s": at(2.0),
        "distance_4s": at(4.0),
    }


def summary_table(title: str, summaries: dict[str, dict[str, float]]) -> Table:
    """A table of :func:`summary`'s figures, one row per label."""
    table = Table(title=title)
    for column in (
        "",
        "falls",
        "mean speed (m/s)",
        "survivors' (m/s)",
        "median m by 1.2 s",
        "by 2 s",
        "by 4 s",
    ):
        table.add_column(column, justify="right")
    for label, s in summaries.items():
        table.add_row(
            label,
            f"{s['fall_rate']:.1%}",
            f"{s['mean_speed']:.2f}",
            f"{s['survivor_speed']:.2f}",
            f"{s['distance_1.2s']:.2f}",
            f"{s['distance_2s']:.2f}",
            f"{s['distance_4s']:.2f}",
        )
    return table


def plot_speeds(
    runs: dict[str, list[tuple[list[float], bool]]],
    hz: float,
    title: str,
    out: Path,
    bin_s: float = 0.4,
) -> None:
    """Median forward speed per ``bin_s`` s against time from the reset, one line per label,
    over its episodes still up in the bin (a PNG at ``out``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    per_bin = round(bin_s * hz)
    for label, episodes in runs.items():
        bins = max(len(d) for d, _ in episodes) // per_bin
        speeds = []
        for b in range(bins):
            up = [
                (d[(b + 1) * per_bin] - d[b * per_bin]) * hz / per_bin
                for d, _ in episodes
                if len(d) > (b + 1) * per_bin
            ]
            speeds.append(np.median(up) if up else np.nan)
        s = summary(episodes, hz, 1.0)
        ax.plot(
            (np.arange(bins) + 0.5) * per_bin / hz,
            speeds,
            marker=".",
            label=f"{label}: {s['fall_rate']:.1%} falls, {s['mean_speed']:.2f} m/s",
        )
    ax.set_xlabel("time from standing (s)")
    ax.set_ylabel("pelvis forward speed, median (m/s)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
