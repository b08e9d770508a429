"""The KL anchor (``--anchor-coef``): a penalty KL(pi || pi_init) that keeps a fine-tuned policy near the
policy it started from (``--init-from``), as RLHF keeps a fine-tuned model near its reference model.

Per batch: the initial policy's Gaussian on the batch's states is computed once (``add_anchor``); every
minibatch then adds ``anchor_weight * anchor_kl`` to the PPO loss.
"""

from __future__ import annotations

import copy

import torch

from dexart_lite.rl.warmstart import action_distribution


def frozen_policy(actor_critic) -> torch.nn.Module:
    """A frozen copy of ``actor_critic``'s policy operator as it is now (the student as loaded, before any
    update)."""
    return copy.deepcopy(actor_critic.get_policy_operator()).requires_grad_(False)


def anchor_weight(cfg, batch: int) -> float:
    """Weight of the KL anchor in batch ``batch`` (0-based): ``anchor_coef``, times ``anchor_decay`` per batch
    after the critic warm-up (none during it: the actor does not learn then), never below ``anchor_floor``."""
    if cfg.anchor_coef == 0 or batch < cfg.critic_warmup:
        return 0.0
    return max(cfg.anchor_coef * cfg.anchor_decay ** (batch - cfg.critic_warmup), cfg.anchor_floor)


def add_anchor(flat, anchor: torch.nn.Module, chunk: int = 1000) -> None:
    """``flat["anchor_loc"]`` and ``flat["anchor_scale"]``, (N, action_dim): the initial policy ``anchor``'s
    action distribution on the batch's states, computed once per batch without gradients."""
    with torch.no_grad():
        parts = [action_distribution(anchor, flat[i:i + chunk]) for i in range(0, flat.numel(), chunk)]
    flat["anchor_loc"], flat["anchor_scale"] = (torch.cat(part) for part in zip(*parts))


def anchor_kl(policy, samples) -> torch.Tensor:
    """Mean over ``samples`` of KL(pi(.|s) || pi_init(.|s)) for diagonal Gaussians, summed over the action
    dimensions (nats); ``policy`` (the current policy operator, its trunk included) is evaluated again here."""
    loc, scale = action_distribution(policy, samples)
    loc0, scale0 = samples["anchor_loc"], samples["anchor_scale"]
    kl = torch.log(scale0 / scale) + (scale ** 2 + (loc - loc0) ** 2) / (2 * scale0 ** 2) - 0.5
    return kl.sum(-1).mean()
