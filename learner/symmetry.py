"""Left-right mirror symmetry for bilateral bodies: the mirror image of an observation and
an action, for PPO's symmetry augmentation (each sample's mirror image is added to the batch
with the same advantage; Abdolhosseini et al. 2019, "On learning symmetric locomotion").

Mirroring is in the sagittal plane: names ending ``_r``/``_l`` (or ``_right``/``_left``)
swap; of the pelvis vectors, the lateral component of ``pelvis_up_*`` and ``pelvis_vel_*``
changes sign, and of the angular velocity (a pseudovector) the other two components do.
Joint angles swap without a sign change: both backends define left and right joint axes so
that the same angle is the same anatomical motion. With the gait clock ``phase_mirror`` (+1
in an episode whose clock plays the motion mirrored) changes sign: the mirror image of a
state at a phase of the motion is one at the same phase of the mirrored motion.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import torch

AXES = "xyz"
_SIDE = re.compile(r"(_r|_l|_right|_left)$")
_PARTNER = {"_r": "_l", "_l": "_r", "_right": "_left", "_left": "_right"}


def _partner(name: str) -> str | None:
    match = _SIDE.search(name)
    return None if match is None else name[: match.start()] + _PARTNER[match.group(1)]


def _permutation(names: list[str], what: str) -> list[int]:
    index = {n: i for i, n in enumerate(names)}
    perm = []
    for name in names:
        partner = _partner(name)
        if partner is not None and partner not in index:
            raise ValueError(f"{what} {name!r} has no mirror partner {partner!r}")
        perm.append(index[partner] if partner is not None else index[name])
    return perm


@dataclass(frozen=True)
class MirrorMap:
    """``mirrored = x[..., perm] * sign`` for observations; actions are only permuted."""

    obs_perm: torch.Tensor
    """[obs_dim] long"""
    obs_sign: torch.Tensor
    """[obs_dim] float32, +-1"""
    act_perm: torch.Tensor
    """[act_dim] long"""

    @classmethod
    def from_names(cls, obs_names: list[str], act_names: list[str], lateral_axis: int) -> MirrorMap:
        """Maps for an env's ``obs_names`` and muscle names; ``lateral_axis`` 0, 1 or 2 is
        the world axis that is neither up nor forward.

        Raises:
            ValueError: a sided name lacks its partner, or the body has no sides at all.
        """
        if not any(_partner(n) for n in act_names):
            raise ValueError("mirror: the body has no left and right muscles to swap")
        lateral = AXES[lateral_axis]
        flipped = {f"{v}_{lateral}" for v in ("pelvis_up", "pelvis_vel")}
        flipped.add("phase_mirror")
        sign = []
        for name in obs_names:
            flip = name in flipped or (
                name.startswith("pelvis_angvel_") and not name.endswith(f"_{lateral}")
            )
            sign.append(-1.0 if flip else 1.0)
        return cls(
            torch.tensor(_permutation(obs_names, "observation"), dtype=torch.long),
            torch.tensor(sign, dtype=torch.float32),
            torch.tensor(_permutation(act_names, "muscle"), dtype=torch.long),
        )

    def obs(self, obs: torch.Tensor) -> torch.Tensor:
        """[N, obs_dim] -> its mirror image [N, obs_dim]."""
        return obs[..., self.obs_perm] * self.obs_sign.to(obs.dtype)

    def action(self, action: torch.Tensor) -> torch.Tensor:
        """[N, act_dim] -> its mirror image [N, act_dim]."""
        return action[..., self.act_perm]


@torch.no_grad()
def add_mirrored(
    batch: dict[str, torch.Tensor], mirror: MirrorMap, policy
) -> dict[str, torch.Tensor]:
    """``batch`` with each sample's mirror image appended (sizes double), and ``"mirrored"``
    [2N] bool marking the images. The mirrored samples keep their advantage and return;
    their behaviour log-probability is the current policy's (the one about to be updated), so
    their first PPO ratio is 1."""
    obs, action = mirror.obs(batch["obs"]), mirror.action(batch["action"])
    logp, _, value = policy.evaluate(obs, action)
    extra = {
        "obs": obs,
        "action": action,
        "logp": logp.to(batch["logp"].dtype),
        "value": value.to(batch["value"].dtype),
    }
    doubled = {key: torch.cat([tensor, extra.get(key, tensor)]) for key, tensor in batch.items()}
    n = batch["obs"].shape[0]
    doubled["mirrored"] = torch.arange(2 * n) >= n
    return doubled
