"""The networks a curriculum stage's transition builds (``learner.trainer`` calls these when a
stage is entered):

- ``continue``: the same network, widened with zero weights if the observation grew
  (``learner.policy.widen_inputs`` on :func:`collapsed`);
- ``scratch``: a fresh network (:func:`fresh_network`);
- a job's ``init_from``: the first network from a checkpoint (:func:`network_from_checkpoint`);
- ``blend`` and ``distil``: :func:`warm_start` rolls pi_old out on the new stage (as a blend
  at alpha 0), fits pi_new's critic (and for ``distil``, or ``blend`` with
  ``blend.clone_actor``, its actor) to that data, and returns
  the blend (``blend``: alpha then ramps 0 -> 1, :func:`ramp_alpha`) or pi_new (``distil``).

After the transition, a stage with ``warm_start`` clones a motion's recorded excitations into
the actor's mean (:func:`excitation_warm_start`, ``learner.clone_excitations``).
:func:`stage_network` runs both for a stage being entered.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path

import torch
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.checkpoint_meta import CheckpointMeta
from gaitforge.learner.clone_excitations import SideGuess, clone_excitations, excitation_table
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.distil import fit_student
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
from gaitforge.workers.scenes import Scene

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
    scene: Scene,
    switch: Switch,
    rollout: Rollout,
) -> ActorCritic:
    """The network stage ``index`` of ``job`` starts with, from ``policy`` (observing
    ``obs_names``): its transition's, then its ``warm_start``'s. Each network that acts in
    between, and the one returned, is passed to ``switch`` (``rollout`` for the warm starts'
    own rollouts on the stage's ``scene``). The first stage's ``continue`` keeps ``policy``
    as built for it (fresh or ``init_from``)."""
    stage = job.stages[index]
    net = stage.network or job.network
    if stage.transition == "continue":
        if index > 0:
            policy, changed = continued(policy, obs_names, io, index, stage.action_std)
            if changed:
                switch(policy)
    else:
        if stage.transition == "scratch":
            policy = fresh_network(io, net)
        else:
            policy = warm_start(policy, obs_names, io, stage, net, job.ppo, rollout, job.seed)
        switch(policy)
    if stage.warm_start is not None:
        policy = excitation_warm_start(policy, io, stage, scene, job.ppo, rollout, job.seed)
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


def warm_start(
    teacher: ActorCritic,
    teacher_obs_names: list[str],
    io: StageIO,
    stage: Stage,
    net: NetworkSpec,
    ppo: PPOSettings,
    rollout: Rollout,
    seed: int,
) -> ActorCritic:
    """``blend`` and ``distil``: pi_new (``net``) fitted to pi_old's (``teacher``'s)
    rollouts on the new stage, ``stage.blend.critic_warmup_env_steps`` of them (its critic
    to their returns; its actor to pi_old's mean actions for ``distil`` and for ``blend``
    with ``stage.blend.clone_actor``); returns the
    blend of the two at alpha 0 (``blend``) or pi_new alone (``distil``)."""
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
        teacher_mean = blended.distribution(batch["obs"]).mean
    fit = fit_student(
        student,
        batch["obs"],
        batch["return"],
        teacher_mean if stage.transition == "distil" or stage.blend.clone_actor else None,
        epochs=stage.blend.fit_epochs,
        seed=seed,
    )
    logger.info("warm start (%s): %s", stage.transition, fit)
    if stage.transition == "distil":
        return student
    blended.new.load_state_dict(student.state_dict())
    return blended


def ramp_alpha(policy: ActorCritic, stage_env_steps: int, blend_start: int, ramp: int) -> bool:
    """Set a blend's alpha for ``stage_env_steps`` (linear from 0 at ``blend_start`` to 1
    ``ramp`` env steps later). True when the blend is finished (alpha 1: pi_old no longer
    acts and the trainer drops it); False for a policy that is not a blend."""
    if not isinstance(policy, BlendedPolicy):
        return False
    alpha = (stage_env_steps - blend_start) / ramp
    policy.set_alpha(alpha)
    return alpha >= 1.0


def excitation_warm_start(
    policy: ActorCritic,
    io: StageIO,
    stage: Stage,
    scene: Scene,
    ppo: PPOSettings,
    rollout: Rollout,
    seed: int,
) -> GaussianPolicy:
    """``stage.warm_start``: ``policy`` (collapsed to one network) with its actor's mean fitted
    to the recorded excitations of ``stage.warm_start.excitations`` at the observed phase,
    and its critic to the returns of the fitted policy's rollouts (``rollout`` gathers them
    on the stage's ``scene``)."""
    from gaitforge.workers.motions import load_motion  # lazy: only warm starts need it

    spec = stage.warm_start
    assert spec is not None
    student = collapsed(policy)
    sides = SideGuess(load_motion(scene.body, spec.excitations))
    report = clone_excitations(
        student,
        io.obs_names,
        io.act_names,
        excitation_table(scene.body, spec.excitations),
        rollout,
        ppo,
        sides,
        env_steps=spec.env_steps,
        rounds=spec.rounds,
        epochs=spec.epochs,
        lr=spec.lr,
        seed=seed,
    )
    logger.info(
        "warm start from the %s excitations: action mse %.4f -> %.4f over %d observations",
        spec.excitations,
        report["action_mse_before"],
        report["action_mse"],
        int(report["observations"]),
    )
    return student
