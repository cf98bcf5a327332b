"""PPO: its settings, the update (clipped surrogate, value loss, entropy bonus, gradient
clipping and an early stop on KL), a batch built from rollout fragments with
:func:`batch_from_fragments`, and :class:`PPO`, the learner that runs these steps on one
policy and its optimizer.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import torch
from gaitforge.learner.gae import compute_gae
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.symmetry import MirrorMap, add_mirrored
from gaitforge.workers.fragment import Fragment
from gaitforge.workers.spec_types import SPEC_VALUES
from pydantic import BaseModel, ConfigDict, Field

LearningRate = Annotated[float, Field(gt=0, le=1)]
"""An Adam learning rate: in (0, 1]."""
EntropyWeight = Annotated[float, Field(ge=0)]
"""A weight of the entropy bonus: >= 0."""


class PPOSettings(BaseModel):
    """PPO settings: the job file's ``ppo:`` section (CleanRL's names and defaults where they
    exist), validated with bounds (numbers strict and finite: ``workers.spec_types``). ``lr``
    and ``entropy_coef`` may follow a linear schedule over each stage (to ``lr_end``,
    ``entropy_coef_end``); :meth:`at` gives the settings at one point of a stage, which
    :func:`ppo_update` takes."""

    model_config = ConfigDict(extra="forbid", frozen=True, **SPEC_VALUES)

    gamma: Annotated[float, Field(gt=0, le=1)] = 0.99
    """discount per control step (dimensionless)"""
    lam: Annotated[float, Field(ge=0, le=1)] = 0.95
    """GAE lambda (dimensionless)"""
    clip: Annotated[float, Field(gt=0, le=1)] = 0.2
    """surrogate clipping range: ratios are clipped to [1 - clip, 1 + clip]"""
    value_coef: Annotated[float, Field(ge=0)] = 0.5
    """weight of the value loss"""
    entropy_coef: EntropyWeight = 0.0
    """weight of the entropy bonus (at the start of each stage)"""
    entropy_coef_end: EntropyWeight | None = None
    """entropy weight at the end of each stage (linear schedule); None: constant"""
    lr: LearningRate = 3e-4
    """Adam learning rate (at the start of each stage)"""
    lr_end: LearningRate | None = None
    """learning rate at the end of each stage (linear schedule); None: constant"""
    critic_lr: LearningRate | None = None
    """the critic's own Adam learning rate, constant over each stage; None: the actor's
    ``lr`` and its schedule (a fine-tune at a low ``lr`` on a new reward otherwise leaves
    the critic far behind the returns, of order 100)"""
    epochs: Annotated[int, Field(ge=1, le=100)] = 5
    """passes over each batch"""
    minibatch_size: Annotated[int, Field(ge=1)] = 2048
    """samples per minibatch (env steps, mirrored ones included): a batch of N samples is
    cut into max(1, round(N / minibatch_size)) minibatches"""
    max_grad_norm: Annotated[float, Field(gt=0)] = 0.5
    """gradient clipping (L2 norm), of the actor's and the critic's parameters apart"""
    target_kl: Annotated[float, Field(gt=0)] | None = 0.03
    """stop the epochs early once the approximate KL exceeds this; None: never"""
    batch_env_steps: Annotated[int, Field(ge=1)] = 8192
    """env steps gathered per update (whole fragments: at least this many)"""
    mirror: bool = False
    """add each sample's left-right mirror image to the batch (bilateral bodies)"""
    decoupled: bool = False
    """clip each update around the policy as it was when the update began (the *proximal*
    policy), not around the one that sampled the batch, and weight each sample by their
    probability ratio (capped at ``MAX_BEHAVIOUR_WEIGHT``): PPO's decoupled objective (Hilton
    et al. 2021, "Batch size-invariance for policy optimization"). The same as plain PPO when
    the batch was sampled by the current weights (in-process rollouts); with Ray actors a
    batch is sampled by the weights of one update before (the trainer's ``policy_lag``)"""

    def at(self, progress: float) -> PPOSettings:
        """These settings ``progress`` (0..1, env steps of the stage over its budget) through
        a stage: ``lr`` and ``entropy_coef`` at that point of their schedules (and the
        schedules' ends dropped, so that the result is constant)."""
        progress = min(1.0, max(0.0, progress))
        lr_end = self.lr if self.lr_end is None else self.lr_end
        ent_end = self.entropy_coef if self.entropy_coef_end is None else self.entropy_coef_end
        return self.model_copy(
            update={
                "lr": self.lr + (lr_end - self.lr) * progress,
                "entropy_coef": self.entropy_coef + (ent_end - self.entropy_coef) * progress,
                "lr_end": None,
                "entropy_coef_end": None,
            }
        )

    def minibatches(self, samples: int) -> int:
        """How many minibatches a batch of ``samples`` samples is cut into."""
        return max(1, round(samples / self.minibatch_size))


MAX_BEHAVIOUR_WEIGHT = 2.0
"""Cap on a sample's weight pi_proximal / pi_behaviour in the decoupled objective (a sample
the previous update made far likelier would otherwise own its minibatch)."""

FROM_ENV = ("obs", "action", "logp", "value", "reward", "bootstrap_value", "last_value")
"""Fragment arrays checked before any arithmetic, so a NaN is named where it entered."""


def batch_from_fragments(fragments: list[Fragment], cfg: PPOSettings) -> dict[str, torch.Tensor]:
    """Flatten fragments ``[T, K, ...]`` into one batch ``[N, ...]`` with advantages and
    returns (GAE per fragment with ``cfg.gamma`` and ``cfg.lam``, bootstrapped on truncation
    and at the fragment end)."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("obs", "action", "logp", "value")}
    advantages, returns = [], []
    for f in fragments:
        check_finite(
            {k: torch.from_numpy(np.asarray(getattr(f, k), dtype=np.float64)) for k in FROM_ENV}
        )
        adv, ret = compute_gae(
            f.reward,
            f.value,
            f.terminated,
            f.truncated,
            f.bootstrap_value,
            f.last_value,
            cfg.gamma,
            cfg.lam,
        )
        advantages.append(adv.reshape(-1))
        returns.append(ret.reshape(-1))
        for key in parts:
            array = getattr(f, key)
            parts[key].append(array.reshape(-1, *array.shape[2:]))
    batch = {key: torch.from_numpy(np.concatenate(v)) for key, v in parts.items()}
    batch["advantage"] = torch.from_numpy(np.concatenate(advantages))
    batch["return"] = torch.from_numpy(np.concatenate(returns))
    check_finite(batch)
    return batch


def check_finite(tensors: dict[str, torch.Tensor]) -> None:
    """Raise ``FloatingPointError`` naming the first tensor with a NaN or Inf."""
    for name, tensor in tensors.items():
        if not torch.isfinite(tensor).all():
            raise FloatingPointError(
                f"{name}: contains NaN or Inf; likely cause: a simulator failure reached the "
                "batch (check the env's health flags) or a diverging value function"
            )


def clipped_surrogate_loss(
    ratio: torch.Tensor, adv: torch.Tensor, clip: float, weight: torch.Tensor | float = 1.0
) -> torch.Tensor:
    """PPO's policy loss: ``-mean(w min(r A, clip(r, 1 - eps, 1 + eps) A))`` over ratios
    ``ratio`` [N], advantages ``adv`` [N] and sample weights ``weight`` ([N] or 1)."""
    return -(weight * torch.min(ratio * adv, ratio.clamp(1 - clip, 1 + clip) * adv)).mean()


def _clip_groups(policy: ActorCritic) -> list[list[torch.nn.Parameter]]:
    """Actor and critic parameters, clipped apart: the value loss (returns of order 100)
    would otherwise own the joint gradient norm and clipping would starve the actor."""
    named = [(n, p) for n, p in policy.named_parameters() if p.requires_grad]
    critic = [p for n, p in named if "critic" in n]
    actor = [p for n, p in named if "critic" not in n]
    return [group for group in (actor, critic) if group]


def optimizer_groups(policy: ActorCritic, critic_apart: bool) -> list[dict]:
    """The policy's trainable parameters as Adam parameter groups: one group, or with
    ``critic_apart`` the actor's and the critic's (named ``"actor"`` and ``"critic"``) for a
    critic learning rate of its own (:func:`set_learning_rates`)."""
    if not critic_apart:
        return [{"params": policy.trainable_parameters(), "name": "all"}]
    actor, critic = _clip_groups(policy)
    return [{"params": actor, "name": "actor"}, {"params": critic, "name": "critic"}]


def set_learning_rates(optimizer: torch.optim.Optimizer, cfg: PPOSettings) -> None:
    """Each parameter group's rate from ``cfg`` (``settings.at(progress)``): the critic's
    ``critic_lr`` where it has a group of its own and a rate set, else ``lr``."""
    for group in optimizer.param_groups:
        critic = group.get("name") == "critic" and cfg.critic_lr is not None
        group["lr"] = cfg.critic_lr if critic else cfg.lr


def ppo_update(
    policy: ActorCritic,
    optimizer: torch.optim.Optimizer,
    batch: dict[str, torch.Tensor],
    cfg: PPOSettings,
    generator: torch.Generator | None = None,
) -> dict[str, float]:
    """Several epochs of minibatch PPO on ``batch`` with ``cfg`` (``settings.at(progress)``:
    its ``lr`` is the optimizer's business, set by the caller); returns the last epoch's
    losses and approximate KL (the mean of its minibatches'; with mirror images in the batch
    also the KL of the sampled ones and of the images apart: ``approx_kl_sampled``,
    ``approx_kl_mirrored``)."""
    n = batch["obs"].shape[0]
    adv = batch["advantage"]
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    proximal_logp, behaviour_weight = _proximal(policy, batch, cfg.decoupled)
    mirrored = batch.get("mirrored")
    stats: dict[str, float] = {}
    for epoch in range(cfg.epochs):
        order = torch.randperm(n, generator=generator)
        kls = []
        sample_kl = torch.zeros(n, dtype=torch.float64)
        for idx in order.chunk(cfg.minibatches(n)):
            logp, entropy, value = policy.evaluate(batch["obs"][idx], batch["action"][idx])
            log_ratio = logp - proximal_logp[idx]
            ratio = log_ratio.exp()
            policy_loss = clipped_surrogate_loss(ratio, adv[idx], cfg.clip, behaviour_weight[idx])
            value_loss = 0.5 * (value - batch["return"][idx]).pow(2).mean()
            loss = policy_loss + cfg.value_coef * value_loss - cfg.entropy_coef * entropy.mean()
            check_finite({"policy_loss": policy_loss, "value_loss": value_loss})
            optimizer.zero_grad()
            loss.backward()
            for group in _clip_groups(policy):
                torch.nn.utils.clip_grad_norm_(group, cfg.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                kl = (ratio - 1) - log_ratio
                kls.append(kl.mean().item())
                sample_kl[idx] = kl.to(sample_kl.dtype)
        stats = {
            "policy_loss": policy_loss.item(),
            "value_loss": value_loss.item(),
            "entropy": entropy.mean().item(),
            "approx_kl": float(np.mean(kls)),
            "epochs": epoch + 1,
            "behaviour_weight": behaviour_weight.mean().item(),
        }
        if mirrored is not None:
            stats["approx_kl_sampled"] = sample_kl[~mirrored].mean().item()
            stats["approx_kl_mirrored"] = sample_kl[mirrored].mean().item()
        if cfg.target_kl is not None and stats["approx_kl"] > cfg.target_kl:
            break
    return stats


def _proximal(
    policy: ActorCritic, batch: dict[str, torch.Tensor], decoupled: bool
) -> tuple[torch.Tensor, torch.Tensor]:
    """The log-probabilities [N] the update's ratios are taken against and each sample's
    weight [N]: the behaviour policy's (``batch["logp"]``) with weights 1 for plain PPO; for
    the decoupled objective the policy's own before the update, weighted by
    pi_proximal / pi_behaviour capped at ``MAX_BEHAVIOUR_WEIGHT``."""
    behaviour = batch["logp"]
    if not decoupled:
        return behaviour, torch.ones_like(behaviour)
    with torch.no_grad():
        proximal = policy.evaluate(batch["obs"], batch["action"])[0].to(behaviour.dtype)
    return proximal, (proximal - behaviour).exp().clamp(max=MAX_BEHAVIOUR_WEIGHT)


class PPO:
    """The learner's side of PPO on one policy, in the steps of rsl_rl's ``PPO``:
    :meth:`compute_returns` turns a batch of rollout fragments into GAE advantages and
    returns, :meth:`update` runs the clipped epochs on them and then merges the batch's
    observations into the normaliser. Acting (rsl_rl's ``act`` and ``process_env_step``) is
    the rollout workers' part, with the weights the trainer publishes.

    Args:
        policy: the network trained; a new network gets a new ``PPO`` (a fresh optimizer).
        critic_apart: give the critic an Adam parameter group of its own (where any stage
            sets ``critic_lr``: the same groups all run long, so a checkpoint resumes).
        lr: Adam's initial learning rate (each update sets the groups' rates from its
            settings).
    """

    def __init__(self, policy: ActorCritic, critic_apart: bool, lr: float) -> None:
        self.policy = policy
        """the network; a finished blend collapses to its pi_new here (the optimizer holds
        pi_new's parameters only, so it goes on)"""
        self.optimizer = torch.optim.Adam(optimizer_groups(policy, critic_apart), lr=lr)

    def compute_returns(
        self, fragments: list[Fragment], cfg: PPOSettings, mirror: MirrorMap | None
    ) -> dict[str, torch.Tensor]:
        """The batch ``[N, ...]`` of ``fragments`` with advantages and returns
        (:func:`batch_from_fragments`), and with ``mirror`` each sample's mirror image added
        (``N`` doubles; ``learner.symmetry``)."""
        batch = batch_from_fragments(fragments, cfg)
        return batch if mirror is None else add_mirrored(batch, mirror, self.policy)

    def update(
        self, batch: dict[str, torch.Tensor], fragments: list[Fragment], cfg: PPOSettings
    ) -> dict[str, float]:
        """PPO's epochs on ``batch`` with ``cfg`` (the stage's settings at this point of its
        schedules, learning rates included), then the observations of ``fragments`` (the
        batch's, unmirrored) merged into the normaliser: after the update, since the batch's
        log-probabilities were taken with the old statistics. Returns the last losses and
        KL (:func:`ppo_update`)."""
        set_learning_rates(self.optimizer, cfg)
        losses = ppo_update(self.policy, self.optimizer, batch, cfg)
        obs = np.concatenate([f.flat_obs() for f in fragments])
        self.policy.norm.update(torch.from_numpy(obs))
        return losses
