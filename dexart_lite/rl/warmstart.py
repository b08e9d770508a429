"""Where a PPO run starts from other than random weights, and the behaviour-cloning term that keeps it there.

* ``--init-from``: a whole actor-critic from a checkpoint (a distilled student or a PPO run): ``initial_weights``.
* ``--obs-norm-steps``: the input normalisation fixed from the initial policy's steps: ``init_normalization``.
* ``--demo-episodes``: the guide's demonstrations, the policy cloned on them (``--bc-warmstart``), and
  ``--dagger-rounds`` in which the clone drives and the guide labels: ``clone_the_guide``.
* ``--bc-coef``: an MSE of the action mean to the demonstrations' labels added to the PPO loss, on the
  ``--demo-episodes`` data or a ``--bc-demos`` folder: ``bc_weight`` and ``bc_loss``.
"""

from __future__ import annotations

import torch

from dexart_lite.demos import load_demos
from dexart_lite.models.actor_critic import HEAD_HIDDEN, POINTS_KEY, STATE_HIDDEN, STATE_KEY, architecture, trunk_of
from dexart_lite.models.pointnet import PointNetEncoder
from dexart_lite.rl.checkpoint import load_checkpoint, policy_function
from dexart_lite.rl.curriculum import guide_demos, guide_env_kwargs


def initial_weights(cfg, state_dim: int, action_dim: int) -> tuple[dict, dict | None]:
    """(``make_actor_critic`` keywords, weights) of ``--init-from`` (its architecture); without it the
    architecture of ``--head`` and ``--state-hidden`` and no weights. ``cfg``: a ``PPOConfig``."""
    own = {"head": cfg.head_widths(), "state_hidden": cfg.state_hidden}
    if not cfg.init_from:
        return own, None
    if own != {"head": HEAD_HIDDEN, "state_hidden": STATE_HIDDEN}:
        raise ValueError("--init-from brings its own architecture: drop --head / --state-hidden")
    payload = load_checkpoint(cfg.init_from)
    source = payload["config"]
    if (source["task"], source["encoder"]) != (cfg.task, cfg.encoder):
        raise ValueError(f"--init-from: {cfg.init_from} is a {source['encoder']} {source['task']} network, "
                         f"not {cfg.encoder} {cfg.task}")
    if (payload["dims"]["state_dim"], payload["dims"]["action_dim"]) != (state_dim, action_dim):
        raise ValueError(f"--init-from: {cfg.init_from} has state/action sizes {payload['dims']['state_dim']}/"
                         f"{payload['dims']['action_dim']}, this env {state_dim}/{action_dim}")
    return architecture(payload["dims"]), payload["model"]


def init_normalization(actor_critic, env_fn, steps: int, seed: int) -> None:
    """Fix the trunk's input normalisation (``Trunk.set_normalization``) from ``steps`` steps of the
    initial, stochastic policy in one env seeded with ``seed``, as torchrl's ``ObservationNorm.init_stats``
    does: the statistics then stay fixed, so every batch is collected and learnt on the same inputs."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    env = env_fn(seed=seed)
    try:
        with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
            td = env.rollout(steps, actor_critic.get_policy_operator(), break_when_any_done=False)
    finally:
        env.close()
    trunk = trunk_of(actor_critic)
    points = td.get(POINTS_KEY, None) if isinstance(trunk.encoder, PointNetEncoder) else None
    trunk.set_normalization(td[STATE_KEY], points)


def action_distribution(policy, samples) -> tuple[torch.Tensor, torch.Tensor]:
    """(loc, scale), each (N, action_dim), of the Gaussian that ``policy`` (a policy operator) puts on the
    point clouds and state vectors of ``samples``."""
    td = policy(samples.select(POINTS_KEY, STATE_KEY, strict=False).clone())
    return td["loc"], td["scale"]


def bc_warmstart(actor_critic, samples, epochs: int, seed: int, lr: float = 1e-3, batch: int = 256,
                 renormalize: bool = True) -> list[float]:
    """Fix the trunk's input normalisation from ``samples`` (the demonstrations; unless ``renormalize`` is
    False), then ``epochs`` passes of Adam on the MSE of the action mean to ``samples["expert_action"]``;
    the mean loss of each epoch."""
    if renormalize:
        trunk_of(actor_critic).set_normalization(samples[STATE_KEY], samples.get(POINTS_KEY, None))
    policy = actor_critic.get_policy_operator()
    params = [p for p in policy.parameters() if p.requires_grad]
    optimizer = torch.optim.Adam(params, lr=lr)
    generator, losses = torch.Generator().manual_seed(seed), []
    for _ in range(epochs):
        total = 0.0
        for idx in torch.randperm(len(samples), generator=generator).split(batch):
            loc, _ = action_distribution(policy, samples[idx])
            loss = torch.nn.functional.mse_loss(loc, samples[idx]["expert_action"])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(samples))
    return losses


def clone_the_guide(cfg, actor_critic) -> tuple:
    """(samples, info): the guide's demonstrations (``--demo-episodes``), the actor cloned on them
    (``--bc-warmstart``) and ``--dagger-rounds`` in which the clone drives and the guide labels. A resumed run
    collects the demonstrations again (same seeds, same data) for the BC term, but neither clones nor runs
    the DAgger rounds again (its weights come from the checkpoint). With ``--init-from`` nothing is cloned:
    the loaded policy drives the DAgger rounds unchanged, so a resumed run (which loads it before the
    checkpoint) collects the same data again."""
    kwargs = guide_env_kwargs(cfg.env_kwargs())
    samples, guide_success = guide_demos(cfg.task, cfg.split, cfg.demo_episodes, cfg.demo_noise, 10_000 + cfg.seed,
                                         kwargs, cfg.guide)
    # an --init-from policy keeps its own input normalisation (the one it was trained with)
    warm = bc_warmstart(actor_critic, samples, cfg.bc_warmstart, cfg.seed,
                        renormalize=not cfg.init_from) if not cfg.resume else []
    info = {"guide_success": guide_success, "warmstart_loss": warm, "dagger_success": []}
    for r in range(cfg.dagger_rounds if cfg.init_from or not cfg.resume else 0):  # the student drives, the guide labels
        visited, success = guide_demos(cfg.task, cfg.split, cfg.demo_episodes, 0.0, 20_000 + 1000 * r + cfg.seed,
                                       kwargs, cfg.guide, driver=policy_function(actor_critic))
        samples = torch.cat([samples, visited])
        info["dagger_success"].append(success)  # the student's own success in this round
        info["warmstart_loss"] += bc_warmstart(actor_critic, samples, cfg.bc_warmstart, cfg.seed + 1 + r,
                                               renormalize=False)
    return samples, {"frames": len(samples), **info}


def demonstrations(cfg, actor_critic) -> tuple:
    """(the BC term's samples or None, what the warm start measured or None): ``clone_the_guide`` with
    ``--demo-episodes`` (after ``--init-from``: its policy drives the DAgger rounds), else the ``--bc-demos``
    folder when the BC term is on."""
    if cfg.demo_episodes:
        return clone_the_guide(cfg, actor_critic)
    return (load_demos(cfg.bc_demos) if cfg.bc_coef > 0 and cfg.bc_demos else None), None


def warmstart_evaluation(cfg, actor_critic) -> dict:
    """Success of the cloned policy before any PPO update, as the final evaluation measures it (seen and unseen
    objects, from the true reset, deterministic): what the demonstrations alone give."""
    from dexart_lite.rl.evaluate import evaluate

    return {split: evaluate(actor_critic, cfg.task, split, cfg.eval_episodes, cfg.eval_seed,
                            cfg.env_kwargs())["success_rate"] for split in ("seen", "unseen")}


# ---------------------------------------------------------------- the BC term of the PPO loss (--bc-coef)
def bc_weight(cfg, batch: int) -> float:
    """Weight of the BC term in batch ``batch`` (0-based): ``bc_coef``, times ``bc_decay`` per batch after
    the critic warm-up (during the warm-up the actor does not learn at all)."""
    if cfg.bc_coef == 0 or batch < cfg.critic_warmup:
        return 0.0
    return cfg.bc_coef * cfg.bc_decay ** (batch - cfg.critic_warmup)


def bc_loss(policy, bc_data, size: int, generator: torch.Generator, device: torch.device) -> torch.Tensor:
    """MSE of ``policy``'s action mean to the expert labels, on ``size`` random samples of ``bc_data``."""
    idx = torch.randint(len(bc_data), (size,), generator=generator)
    samples = bc_data[idx].to(device)
    loc, _ = action_distribution(policy, samples)
    return torch.nn.functional.mse_loss(loc, samples["expert_action"])
