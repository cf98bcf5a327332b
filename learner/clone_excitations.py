"""Warm start from recorded excitations: the actor's mean excitation fitted, before PPO, to
the excitations that computed muscle control (CMC) found for a recorded gait, as a function
of the gait phase the scene's clock puts in the observation (``phase_sin``, ``phase_cos``).

Behavioural cloning on the states the policy visits: roll out in the stage's imitation scene
(every episode starts inside the motion, at a random phase: reference state initialisation),
label each observation with the recorded excitations at its phase (left and right muscles
swapped when the episode is mirrored, as ``phase_mirror`` in the observation says, or else
the observed joint angles: :class:`SideGuess`), fit the actor's mean by squared error
(``learner.distil.fit_student``); then roll out the fitted policy, add its observations and
fit again (``rounds``, DAgger-like), and fit the critic to the last round's returns. The
rollouts go through the trainer's sampler and count in the stage's env steps.

The excitation table comes from the motions package (``workers.motions.load_excitations``):
one periodic cycle of the recorded excitations, ``[N, n_muscles]`` at phases ``k / N``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

import numpy as np
import torch
from gaitforge.learner.distil import fit_student
from gaitforge.learner.policy import ActorCritic, GaussianPolicy
from gaitforge.learner.ppo import PPOSettings, batch_from_fragments
from gaitforge.workers.fragment import Fragment

if TYPE_CHECKING:
    from gaitforge.workers.motions import Motion

logger = logging.getLogger(__name__)

PHASE_NAMES = ("phase_sin", "phase_cos")
"""the observation's entries the phase is read from: sin and cos of 2 pi phase"""
MIRROR_NAME = "phase_mirror"
"""the observation's entry that says an episode is mirrored (+1) or not (-1)"""
JOINT_PREFIX = "q:"
"""observation entries of joint angles (rad): ``q:<dof name>``"""

Rollout = Callable[[ActorCritic, int], list[Fragment]]
"""``rollout(policy, env_steps)``: fragments of ``policy`` (see ``learner.transitions``)"""


class ExcitationError(ValueError):
    """No recorded excitations for a body and motion, or a table that does not fit; the
    message is one line."""


@dataclass(frozen=True)
class ExcitationTable:
    """One periodic cycle of recorded excitations.

    Attributes:
        muscles: muscle names, [M].
        values: [N, M] excitations in [0, 1] at phases ``k / N``, k = 0..N-1.
    """

    muscles: list[str]
    values: np.ndarray

    def at(self, phase: np.ndarray) -> np.ndarray:
        """[B] phases (wrapped into [0, 1)) -> [B, M] excitations, linear between samples,
        periodic across the seam."""
        n = len(self.values)
        x = np.mod(np.asarray(phase, dtype=np.float64), 1.0) * n
        k = np.floor(x).astype(int) % n
        w = (x - np.floor(x))[:, None]
        return (1.0 - w) * self.values[k] + w * self.values[(k + 1) % n]

    def columns(self, act_names: list[str], mirrored: bool = False) -> np.ndarray:
        """Indices into :attr:`muscles` of each action entry [A] (``_r`` and ``_l`` swapped
        when ``mirrored``).

        Raises:
            ExcitationError: an action's muscle has no recorded excitation.
        """
        index = {name: i for i, name in enumerate(self.muscles)}
        names = [mirror_name(n) for n in act_names] if mirrored else list(act_names)
        missing = [n for n in names if n not in index]
        if missing:
            raise ExcitationError(
                f"no recorded excitation for muscles {missing[:4]} (recorded: "
                f"{self.muscles[:4]}...)"
            )
        return np.array([index[n] for n in names], dtype=int)


def mirror_name(name: str) -> str:
    """``x_r`` <-> ``x_l``; other names unchanged."""
    if name.endswith("_r"):
        return name[:-2] + "_l"
    if name.endswith("_l"):
        return name[:-2] + "_r"
    return name


@cache
def excitation_table(body: str, motion: str) -> ExcitationTable:
    """The recorded excitations of ``motion`` for ``body`` (``workers.motions``).

    Raises:
        ExcitationError: none recorded for that body and motion (naming what there is).
    """
    from gaitforge.workers import motions  # lazy: only jobs with a warm start need it

    try:
        recorded = motions.load_excitations(body, motion)  # muscle -> [N], phases k / N
    except motions.MotionError as exc:
        raise ExcitationError(str(exc)) from None
    muscles = list(recorded)
    values = np.stack([np.asarray(recorded[m], dtype=np.float64) for m in muscles], axis=1)
    return ExcitationTable(muscles, np.clip(values, 0.0, 1.0))


def phases_of(obs: np.ndarray, obs_names: list[str]) -> np.ndarray:
    """[N, obs_dim] observations -> [N] gait phases in [0, 1) from their sin and cos.

    Raises:
        ExcitationError: the observation has no phase (the scene has no gait clock).
    """
    missing = [n for n in PHASE_NAMES if n not in obs_names]
    if missing:
        raise ExcitationError(f"the observation has no {missing} (the scene has no gait clock)")
    s = obs[:, obs_names.index(PHASE_NAMES[0])].astype(np.float64)
    c = obs[:, obs_names.index(PHASE_NAMES[1])].astype(np.float64)
    return np.mod(np.arctan2(s, c) / (2 * math.pi), 1.0)


class SideGuess:
    """Whether an observation comes from a mirrored episode (the env swaps left and right at
    random; the phase in the observation is the same either way): the observed joint angles
    are nearer the motion's mirrored reference at that phase than its own.

    Args:
        motion: the motion the scene imitates (``workers.motions.Motion``).
    """

    def __init__(self, motion: Motion) -> None:
        n = motion.samples
        states = [motion.at(k / n) for k in range(n)]
        self.joints = list(motion.joints)
        own = np.array([[s.joints[j] for j in self.joints] for s in states])
        flipped = [motion.mirrored_state(s) for s in states]
        mirrored = np.array([[s.joints[j] for j in self.joints] for s in flipped])
        self._own = ExcitationTable(self.joints, own)
        self._mirrored = ExcitationTable(self.joints, mirrored)

    def margin(self, obs: np.ndarray, obs_names: list[str]) -> np.ndarray:
        """[N, obs_dim] -> [N] squared distance (rad^2) of the observed joint angles to the
        reference minus that to the mirrored reference: > 0 looks mirrored (0 where no joint
        angle of the motion is observed)."""
        cols = [
            (i, obs_names.index(JOINT_PREFIX + j))
            for i, j in enumerate(self.joints)
            if JOINT_PREFIX + j in obs_names
        ]
        if not cols:
            return np.zeros(len(obs))
        ref_cols, obs_cols = (np.array(c) for c in zip(*cols, strict=True))
        phases = phases_of(obs, obs_names)
        q = obs[:, obs_cols].astype(np.float64)
        own = np.sum((q - self._own.at(phases)[:, ref_cols]) ** 2, axis=1)
        flipped = np.sum((q - self._mirrored.at(phases)[:, ref_cols]) ** 2, axis=1)
        return own - flipped

    def mirrored(self, obs: np.ndarray, obs_names: list[str]) -> np.ndarray:
        """[N, obs_dim] -> [N] bool: each observation on its own looks mirrored."""
        return self.margin(obs, obs_names) > 0

    def mirrored_episodes(self, fragments: list[Fragment], obs_names: list[str]) -> np.ndarray:
        """[N] bool over the fragments' steps (flattened as ``batch_from_fragments`` does:
        fragment by fragment, time-major): whether each step's episode is mirrored, decided
        once per episode (its margins summed over its steps in the fragment), since an
        episode keeps its side from reset to end."""
        out = []
        for f in fragments:
            t_len, k_len = f.obs.shape[:2]
            margin = self.margin(f.obs.reshape(t_len * k_len, -1), obs_names).reshape(t_len, k_len)
            ends = np.asarray(f.terminated) | np.asarray(f.truncated)
            flags = np.zeros((t_len, k_len), dtype=bool)
            for k in range(k_len):
                start = 0
                for t in [*np.flatnonzero(ends[:, k]), t_len - 1]:
                    if t >= start:
                        flags[start : t + 1, k] = margin[start : t + 1, k].sum() > 0
                        start = t + 1
            out.append(flags.reshape(-1))
        return np.concatenate(out) if out else np.zeros(0, dtype=bool)


def excitation_labels(
    obs: np.ndarray,
    obs_names: list[str],
    act_names: list[str],
    table: ExcitationTable,
    mirrored: np.ndarray | None = None,
) -> np.ndarray:
    """[N, obs_dim] observations -> [N, A] the recorded excitations at each one's phase, in
    the order of ``act_names``; left and right swapped where ``mirrored`` [N] is True."""
    at = table.at(phases_of(obs, obs_names))
    labels = at[:, table.columns(act_names)]
    if mirrored is not None and mirrored.any():
        labels[mirrored] = at[mirrored][:, table.columns(act_names, mirrored=True)]
    return labels


@torch.no_grad()
def action_error(policy: GaussianPolicy, obs: torch.Tensor, labels: torch.Tensor) -> float:
    """Mean squared difference between the deterministic action and ``labels`` [N, A]."""
    return float((policy.mean_action(obs.float()) - labels.float()).pow(2).mean())


def clone_excitations(
    policy: GaussianPolicy,
    obs_names: list[str],
    act_names: list[str],
    table: ExcitationTable,
    rollout: Rollout,
    ppo: PPOSettings,
    sides: SideGuess | None = None,
    *,
    env_steps: int = 8192,
    rounds: int = 2,
    epochs: int = 30,
    lr: float = 1e-3,
    rollout_std: float | None = 0.05,
    seed: int = 0,
) -> dict[str, float]:
    """Fit ``policy``'s mean excitation to ``table`` at the phases of the observations it
    visits (see the module's docstring); ``policy`` is changed in place (actor, critic and
    the observation normaliser). Mirrored episodes' labels swap left and right: the
    observation's ``phase_mirror`` tells them, or else ``sides`` (None: none mirrored). The
    rollouts act with the standard deviation ``rollout_std`` (None: the policy's own),
    restored after: near-deterministic rollouts visit the states a deterministic policy sees
    (previous excitations are in the observation, and exploration noise makes them unlike
    its own).

    Returns diagnostics: ``action_mse_before`` and ``action_mse`` (the deterministic action
    against the labels on every observation gathered, before and after), ``value_mse`` (the
    critic's last fit), ``observations`` (how many were labelled).
    """
    all_obs: list[torch.Tensor] = []
    all_labels: list[torch.Tensor] = []
    report: dict[str, float] = {}
    for r in range(rounds):
        log_std = policy.log_std.detach().clone()
        if rollout_std is not None:
            with torch.no_grad():
                policy.log_std.fill_(math.log(rollout_std))
        try:
            fragments = rollout(policy, env_steps)
        finally:
            with torch.no_grad():
                policy.log_std.copy_(log_std)
        batch = batch_from_fragments(fragments, ppo)
        obs = batch["obs"]
        raw = obs.numpy()
        if MIRROR_NAME in obs_names:  # the scene says it
            mirrored = raw[:, obs_names.index(MIRROR_NAME)] > 0
        else:
            mirrored = None if sides is None else sides.mirrored_episodes(fragments, obs_names)
        labels = torch.from_numpy(excitation_labels(raw, obs_names, act_names, table, mirrored))
        policy.norm.update(obs)
        all_obs.append(obs)
        all_labels.append(labels)
        obs_all, labels_all = torch.cat(all_obs), torch.cat(all_labels)
        if r == 0:
            report["action_mse_before"] = action_error(policy, obs_all, labels_all)
        fit = fit_student(policy, obs_all, None, labels_all, epochs=epochs, lr=lr, seed=seed + r)
        if r == rounds - 1:
            value = fit_student(
                policy, obs, batch["return"], None, epochs=epochs, lr=lr, seed=seed + r
            )
            report["value_mse"] = value["value_mse"]
        report["action_mse"] = action_error(policy, obs_all, labels_all)
        logger.info("warm start round %d: %d observations, %s", r + 1, len(obs_all), fit)
    report["observations"] = float(sum(len(o) for o in all_obs))
    return report
