"""The networks a curriculum stage's transition builds (``learner.trainer`` calls
:func:`stage_network` when a stage is entered):

- ``continue``: the same network, widened with zero weights if the observation grew
  (``learner.policy.widen_inputs`` on :func:`collapsed`);
- a job's ``init_from``: the first network from a checkpoint (:func:`network_from_checkpoint`);
- ``blend``: :func:`blend_in` rolls pi_old out on the new stage (as a blend at alpha 0), fits
  pi_new's critic to that data (:func:`fit_critic`), and returns the blend (alpha then ramps
  0 -> 1, :func:`ramp_alpha`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path

import torch
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.checkpoint_meta import CheckpointMeta
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.job import Job, NetworkSpec, Stage
from gaitforge.learner.policy import (
    ActorCritic,
    BlendedPolicy,
    GaussianPolicy,
    release_constant_inputs,
    widen_inputs,
)
from gaitforge.learner.ppo import PPOSettings, batch_from_fragments
from gaitforge.workers.fragment import Fragment

logger = logging.getLogger(__name__)

Rollout = Callable[[ActorCritic, int], list[Fragment]]
"""``rollout(policy, env_steps)``: make ``policy`` the acting one and gather at least
``env_steps`` env steps of its fragments (they count in the stage's env steps)."""

Switch = Callable[[ActorCritic], None]
"""``switch(policy)``: make ``policy`` (a new network, or the same one changed) the acting one
(a fresh optimizer over it, its weights published to the rollout workers)."""


def stage_network(
    policy: ActorCritic,
    obs_names: list[str],
    index: int,
    job: Job,
    io: StageIO,
    switch: Switch,
    rollout: Rollout,
) -> ActorCritic:
    """The network stage ``index`` of ``job`` starts with, from ``policy`` (observing
    ``obs_names``), by its transition. Each network that acts in between, and the one
    returned, is passed to ``switch`` (``rollout`` for the blend's own rollouts). The first
    stage's ``continue`` keeps ``policy`` as built for it (fresh or ``init_from``)."""
    stage = job.stages[index]
    if stage.transition == "continue":
        if index > 0:
            policy, changed = continued(policy, obs_names, io, index, stage.action_std)
            if changed:
                switch(policy)
        return policy
    net = stage.network or job.network
    policy = blend_in(policy, obs_names, io, stage, net, job.ppo, rollout, job.seed)
    switch(policy)
    return policy


def collapsed(policy: ActorCritic) -> GaussianPolicy:
    """``policy`` as one network (a blend is its new network)."""
    while isinstance(policy, BlendedPolicy):
        policy = policy.new
    assert isinstance(policy, GaussianPolicy)
    return policy


def continued(
    policy: ActorCritic,
    obs_names: list[str],
    io: StageIO,
    index: int,
    action_std: float | None = None,
) -> tuple[ActorCritic, bool]:
    """The ``continue`` transition into stage ``index``: ``policy`` (observing ``obs_names``)
    widened with zero weights if the stage observes more, its inputs that were constant
    so far released (``release_constant_inputs``), and if ``action_std`` is given its action
    noise started anew there (:func:`reset_action_std`); True if the network changed."""
    widen = io.obs_names != obs_names
    if widen:
        policy = widen_inputs(collapsed(policy), obs_names, io.obs_names)
    released = release_constant_inputs(policy) if isinstance(policy, GaussianPolicy) else []
    if released:
        logger.info(
            "stage %d: inputs constant so far, released: %s",
            index,
            [io.obs_names[i] for i in released],
        )
    if action_std is not None:
        reset_action_std(policy, action_std)
        logger.info("stage %d: action noise started anew at std %g", index, action_std)
    return policy, bool(widen or released or action_std is not None)


def reset_action_std(policy: ActorCritic, action_std: float) -> None:
    """Set every action entry's noise standard deviation (action units) to ``action_std``, in
    place; for a blend, both networks' (so the blend's is exactly that at any alpha)."""
    networks = [policy.old, policy.new] if isinstance(policy, BlendedPolicy) else [policy]
    with torch.no_grad():
        for network in networks:
            network.log_std.fill_(math.log(action_std))


def fresh_network(io: StageIO, net: NetworkSpec) -> GaussianPolicy:
    """A new network for the stage's observations and muscles."""
    return GaussianPolicy(len(io.obs_names), len(io.act_names), tuple(net.hidden), net.init_std)


def network_from_checkpoint(
    path: Path,
    io: StageIO,
    scene_name: str,
    action_std: float | None = None,
) -> tuple[GaussianPolicy, CheckpointMeta]:
    """A job's ``init_from``: checkpoint ``path``'s network (collapsed to one) with its
    observation statistics, widened if the first stage (``io``, scene ``scene_name``)
    observes more, its constant inputs released, its action noise reset to ``action_std``
    (every action entry; None: kept); in training mode. Returns it and the checkpoint's
    metadata.

    Raises:
        ValueError: the checkpoint acts on other entries, or observes what the stage does not.
    """
    loaded, meta = load_policy(path)
    policy = collapsed(loaded)
    if action_std is not None:
        reset_action_std(policy, action_std)
    if policy.act_dim != len(io.act_names):
        raise ValueError(
            f"init_from: {path} acts on {policy.act_dim} entries; stage 0's scene "
            f"{scene_name!r} on {len(io.act_names)} ({io.act_names[:3]}...)"
        )
    names = meta.obs_names or []
    if names != io.obs_names:
        missing = [n for n in names if n not in io.obs_names]
        if missing or len(names) != policy.obs_dim:
            raise ValueError(
                f"init_from: {path} observes {missing[:5]} that stage 0's scene "
                f"{scene_name!r} does not"
            )
        policy = widen_inputs(policy, names, io.obs_names)
    release_constant_inputs(policy)
    policy.train()
    return policy, meta


def blend_in(
    teacher: ActorCritic,
    teacher_obs_names: list[str],
    io: StageIO,
    stage: Stage,
    net: NetworkSpec,
    ppo: PPOSettings,
    rollout: Rollout,
    seed: int,
) -> BlendedPolicy:
    """``blend``: pi_new (``net``) with its critic fitted to pi_old's (``teacher``'s)
    rollouts on the new stage, ``stage.blend.critic_warmup_env_steps`` of them; returns the
    blend of the two at alpha 0."""
    student = fresh_network(io, net)
    old_inputs = [io.obs_names.index(n) for n in teacher_obs_names]
    blended = BlendedPolicy(teacher.describe(), student.describe(), old_inputs)
    blended.old.load_state_dict(teacher.state_dict())
    blended.new.load_state_dict(student.state_dict())
    fragments = rollout(blended, max(1, stage.blend.critic_warmup_env_steps))
    batch = batch_from_fragments(fragments, ppo)
    student.norm.update(batch["obs"])
    with torch.no_grad():
        student.log_std.copy_(blended.distribution(batch["obs"][:1]).stddev.log()[0])
    value_mse = fit_critic(
        student, batch["obs"], batch["return"], epochs=stage.blend.fit_epochs, seed=seed
    )
    logger.info("blend: the new critic fitted to pi_old's returns, value mse %.4g", value_mse)
    blended.new.load_state_dict(student.state_dict())
    return blended


def fit_critic(
    student: GaussianPolicy,
    obs: torch.Tensor,
    returns: torch.Tensor,
    epochs: int = 50,
    minibatch: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
) -> float:
    """Regress ``student``'s value on ``returns`` [N] from ``obs`` [N, obs_dim] by squared
    error (the normaliser is used as it is, not updated; only the critic changes). Returns
    the last epoch's mean squared error."""
    generator = torch.Generator().manual_seed(seed)
    optimizer = torch.optim.Adam(list(student.critic.parameters()), lr=lr)
    obs, returns = obs.float(), returns.float()
    value_mse = 0.0
    for _ in range(epochs):
        value_mse = 0.0
        chunks = torch.randperm(len(obs), generator=generator).split(minibatch)
        for idx in chunks:
            loss = (student.value(obs[idx]) - returns[idx]).pow(2).mean()
            value_mse += loss.item() / len(chunks)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return value_mse


def ramp_alpha(policy: ActorCritic, stage_env_steps: int, blend_start: int, ramp: int) -> bool:
    """Set a blend's alpha for ``stage_env_steps`` (linear from 0 at ``blend_start`` to 1
    ``ramp`` env steps later). True when the blend is finished (alpha 1: pi_old no longer
    acts and the trainer drops it); False for a policy that is not a blend."""
    if not isinstance(policy, BlendedPolicy):
        return False
    alpha = (stage_env_steps - blend_start) / ramp
    policy.set_alpha(alpha)
    return alpha >= 1.0
