"""Policy networks: ``GaussianPolicy`` (an actor-critic over excitations in [0, 1]) and
``BlendedPolicy`` (a new, larger network trained in blend with a frozen previous one).

Both implement ``workers.policy_api.RolloutPolicy``: ``act`` samples from a diagonal
Gaussian whose mean is squashed into [0, 1] by a sigmoid; the sample itself is returned (the
env clips it to [0, 1]) so that its log-probability is exact for the PPO ratio.

A policy is rebuilt from its *description* (``policy.describe()``, a JSON-able dict kept in
checkpoints and handed to rollout actors): ``build_policy(desc)`` makes the same structure,
and ``load_state_dict`` fills it in.
"""

from __future__ import annotations

import itertools

import torch
from gaitforge.learner.normalizer import RunningNorm
from torch import nn
from torch.distributions import Normal


def _mlp(sizes: list[int], out: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), nn.Tanh()]
    layers.append(nn.Linear(sizes[-1], out))
    return nn.Sequential(*layers)


class ActorCritic(nn.Module):
    """What every policy derives from ``distribution`` and ``value``."""

    norm: RunningNorm
    """the normaliser the learner updates from its batches"""

    def distribution(self, obs: torch.Tensor) -> Normal:  # pragma: no cover - abstract
        raise NotImplementedError

    def value(self, obs: torch.Tensor) -> torch.Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def describe(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def act(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """obs [K, obs_dim] -> sampled action [K, act_dim], its log-probability [K], V [K]."""
        dist = self.distribution(obs)
        action = dist.sample()
        return action, dist.log_prob(action).sum(-1), self.value(obs)

    def mean_action(self, obs: torch.Tensor) -> torch.Tensor:
        """obs [K, obs_dim] -> the deterministic action [K, act_dim] (the mean, in [0, 1])."""
        return self.distribution(obs).mean

    def evaluate(
        self, obs: torch.Tensor, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Log-probability [N], entropy [N] and value [N] of ``action`` [N, act_dim]."""
        dist = self.distribution(obs)
        return dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(obs)

    def trainable_parameters(self) -> list[nn.Parameter]:
        return [p for p in self.parameters() if p.requires_grad]


class GaussianPolicy(ActorCritic):
    """Actor and critic MLPs over a normalised observation.

    Args:
        obs_dim, act_dim: sizes of observation and action (muscles).
        hidden: hidden layer widths of both networks.
        init_std: initial standard deviation of the excitations.
    """

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: tuple[int, ...] = (64, 64), init_std: float = 0.3
    ) -> None:
        super().__init__()
        self.obs_dim, self.act_dim, self.hidden = obs_dim, act_dim, tuple(hidden)
        self.init_std = init_std
        self.norm = RunningNorm(obs_dim)
        self.actor = _mlp([obs_dim, *hidden], act_dim)
        self.critic = _mlp([obs_dim, *hidden], 1)
        self.log_std = nn.Parameter(
            torch.full((act_dim,), float(torch.log(torch.tensor(init_std))))
        )

    def describe(self) -> dict:
        return {
            "class": "GaussianPolicy",
            "obs_dim": self.obs_dim,
            "act_dim": self.act_dim,
            "hidden": list(self.hidden),
            "init_std": self.init_std,
        }

    def act_neutrally(self) -> None:
        """Zero the actor's output layer: the mean action is 0.5 for every observation (a
        reflex gait controller's residual of nothing) until training moves it."""
        output = self.actor[-1]
        assert isinstance(output, nn.Linear)
        with torch.no_grad():
            output.weight.zero_()
            output.bias.zero_()

    def mean_logits(self, obs: torch.Tensor) -> torch.Tensor:
        """obs [N, obs_dim] -> the actor's output before the sigmoid [N, act_dim]."""
        return self.actor(self.norm(obs))

    def distribution(self, obs: torch.Tensor) -> Normal:
        """obs [N, obs_dim] -> Normal over actions [N, act_dim] (mean in [0, 1])."""
        mean = torch.sigmoid(self.mean_logits(obs))
        return Normal(mean, self.log_std.exp().expand_as(mean))

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """obs [N, obs_dim] -> V(s) [N]."""
        return self.critic(self.norm(obs)).squeeze(-1)


class BlendedPolicy(ActorCritic):
    """pi_new trained in blend with a frozen pi_old (deepsense.ai, NIPS 2017 Learning to Run).

    Action mean ``(1 - alpha) * mean_old(s) + alpha * mean_new(s)`` and log standard deviation
    blended the same way, so alpha = 0 is exactly pi_old and alpha = 1 exactly pi_new. The
    value is pi_new's critic (warm-started by the trainer). ``alpha`` is a buffer: it travels
    with the weights to the rollout actors and into checkpoints.

    Args:
        old: description of pi_old (its parameters are loaded afterwards and frozen).
        new: description of pi_new; its observation is the stage's whole observation.
        old_inputs: indices into the new observation of pi_old's inputs (pi_old may have been
            trained on fewer observations), or None for the same observation.
    """

    def __init__(self, old: dict, new: dict, old_inputs: list[int] | None = None) -> None:
        super().__init__()
        self.old = build_policy(old)
        self.new = build_policy(new)
        self.old.requires_grad_(False)
        index = torch.tensor(
            old_inputs if old_inputs is not None else range(self.new.obs_dim), dtype=torch.long
        )
        self.register_buffer("old_inputs", index)
        self.register_buffer("alpha", torch.tensor(0.0, dtype=torch.float64))

    @property
    def norm(self) -> RunningNorm:  # type: ignore[override]
        return self.new.norm

    def describe(self) -> dict:
        return {
            "class": "BlendedPolicy",
            "old": self.old.describe(),
            "new": self.new.describe(),
            "old_inputs": self.old_inputs.tolist(),
        }

    def set_alpha(self, alpha: float) -> None:
        self.alpha.fill_(min(1.0, max(0.0, alpha)))

    def distribution(self, obs: torch.Tensor) -> Normal:
        a = self.alpha.to(obs.dtype)
        with torch.no_grad():
            old = self.old.distribution(obs[:, self.old_inputs])
        new = self.new.distribution(obs)
        mean = (1 - a) * old.mean + a * new.mean
        log_std = (1 - a) * old.stddev.log() + a * new.stddev.log()
        return Normal(mean, log_std.exp())

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.new.value(obs)


def build_policy(desc: dict) -> ActorCritic:
    """The network ``desc`` (from ``describe()``) describes, freshly initialised."""
    kind = desc.get("class")
    if kind == "GaussianPolicy":
        return GaussianPolicy(
            desc["obs_dim"], desc["act_dim"], tuple(desc["hidden"]), desc.get("init_std", 0.3)
        )
    if kind == "BlendedPolicy":
        return BlendedPolicy(desc["old"], desc["new"], desc.get("old_inputs"))
    raise ValueError(f"network class {kind!r}: expected GaussianPolicy or BlendedPolicy")


@torch.no_grad()
def widen_inputs(
    policy: GaussianPolicy, old_names: list[str], new_names: list[str]
) -> GaussianPolicy:
    """``policy`` carried to a longer observation ``new_names`` (a superset of ``old_names``):
    the first layers get zero weights for the new inputs and the normaliser keeps its
    statistics by name, so the actions are unchanged until training uses the new inputs."""
    missing = [n for n in old_names if n not in new_names]
    if missing:
        raise ValueError(f"observation lost between stages: {missing[:5]}")
    index = torch.tensor([new_names.index(n) for n in old_names], dtype=torch.long)
    wider = GaussianPolicy(len(new_names), policy.act_dim, policy.hidden, policy.init_std)
    state = wider.state_dict()
    for key, value in policy.state_dict().items():
        if key in ("actor.0.weight", "critic.0.weight"):
            state[key].zero_()
            state[key][:, index] = value
        elif key in ("norm.mean", "norm.var"):
            state[key][index] = value
        else:
            state[key] = value
    wider.load_state_dict(state)
    return wider


CONSTANT_VAR = 1e-6
"""An input whose running variance is below this was constant in every batch so far."""


@torch.no_grad()
def release_constant_inputs(policy: GaussianPolicy) -> list[int]:
    """Make ``policy`` ready for inputs that were constant so far and may not be from now on
    (a stage with another target speed): their first-layer weights are zeroed and their
    variance set to 1. Normalised, such an input was always 0, so its weights never moved
    from their random start and never changed an action; with a new value (clipped to +-10)
    they would. After this the actions are unchanged for any value of those inputs until
    training uses them. Returns their indices (in place; the policy is changed)."""
    constant = torch.nonzero(policy.norm.var < CONSTANT_VAR).flatten()
    if len(constant):
        policy.actor[0].weight[:, constant] = 0.0
        policy.critic[0].weight[:, constant] = 0.0
        policy.norm.var[constant] = 1.0
    return constant.tolist()
