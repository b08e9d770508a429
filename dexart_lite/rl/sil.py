"""Self-imitation learning (Oh et al. 2018, "Self-Imitation Learning", ICML): PPO learns from its own best episodes.

Why: on 2 cores PPO from scratch collects a success now and then (faucet: about one episode in 40-130 in
the state-only diagnostic) but does not build on it: one successful episode among ~16 in a 4k-frame batch
is one clipped policy-gradient step, and it is gone from the next batch. SIL keeps the best episodes the
policy has produced so far and, at every PPO minibatch step, also imitates their actions where their
return beat the critic's estimate:

    L_sil = - mean_i[ log pi(a_i | s_i) * (R_i - V(s_i))+ ]  +  value_coef * mean_i[ 0.5 * ((R_i - V(s_i))+)^2 ]

``R_i``: the discounted Monte-Carlo return from step i to the end of its episode (rewards times the run's
``reward_scale``, as the critic sees them); ``(x)+ = max(x, 0)``, so a stored step whose return the
critic already expects teaches nothing, and the policy is only ever pulled towards actions that did
better than expected (SIL's lower-bound argument). This is not DexArt (whose PPO has no replay).

``SelfImitationBuffer`` keeps whole episodes, the highest episode returns first, up to ``capacity``
steps; only episodes that end inside a collected batch are stored (an episode's first steps may belong
to the previous batch: their part in this batch still has its exact return to the end). Sampling is
uniform over the stored steps (the paper prioritises by ``(R - V)+``; uniform is simpler and the
clipping already zeroes the steps that teach nothing). A resumed run starts with an empty buffer.

Measured (README, 2 seeds each, weight 1): from scratch on the state-only faucet and laptop, no change in
300k frames; fine-tuning faucet students, seen success up and unseen down, as without it
(benchmarks/results/rl/state_diagnostic_fast_sil_{faucet,laptop}.json, finetune_faucet_sil.json).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from dexart_lite.models.actor_critic import POINTS_KEY, STATE_KEY

RETURN_KEY = "sil_return"


def episode_returns(reward: torch.Tensor, done: torch.Tensor, gamma: float) -> torch.Tensor:
    """Discounted returns to the end of each episode, for one worker's trajectory.

    ``reward``, ``done``: (T,) float and bool, ``done[t]``: the episode ended after step t (terminated
    or truncated). Returns (T,). The steps after the trajectory's last ``done`` get the return of the part
    collected so far (their episode goes on in the next batch); ``SelfImitationBuffer`` never stores them."""
    returns = torch.zeros_like(reward)
    running = 0.0
    for t in range(reward.shape[0] - 1, -1, -1):
        if done[t]:
            running = 0.0
        running = float(reward[t]) + gamma * running
        returns[t] = running
    return returns


class SelfImitationBuffer:
    """The best complete episodes collected so far (by episode return), at most ``capacity`` steps."""

    def __init__(self, capacity: int, gamma: float, keys: tuple[str, ...] = (POINTS_KEY, STATE_KEY, "action")):
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1 step, got {capacity}")
        self.capacity, self.gamma, self.keys = capacity, gamma, keys
        self.episodes: list[tuple[float, TensorDict]] = []  # (episode return, its steps), best first
        self.steps: TensorDict | None = None  # the stored steps in one TensorDict, rebuilt by ``add``

    def __len__(self) -> int:
        return 0 if self.steps is None else self.steps.batch_size[0]

    def best_return(self) -> float:
        return self.episodes[0][0] if self.episodes else float("nan")

    def add(self, data: TensorDict) -> int:
        """Store the episodes that end in ``data`` (a collected batch, (workers, T) or (T,), rewards already
        scaled); keep the best ones within ``capacity``. Returns the number of episodes added."""
        batch = data if data.ndim == 2 else data.unsqueeze(0)
        keys = [k for k in self.keys if k in batch.keys()]
        added = 0
        for w in range(batch.shape[0]):
            traj = batch[w]
            done = traj["next", "done"].reshape(-1)
            returns = episode_returns(traj["next", "reward"].reshape(-1).float(), done, self.gamma)
            ends = torch.nonzero(done).reshape(-1).tolist()
            start = 0
            for end in ends:  # steps start..end are one episode (or its tail, if it began in the last batch)
                steps = traj[start:end + 1].select(*keys).clone()
                steps[RETURN_KEY] = returns[start:end + 1]
                score = float(traj["next", "reward"][start:end + 1].sum())  # undiscounted, the episode's tail
                self.episodes.append((score, steps))
                added += 1
                start = end + 1  # steps start.. after the last end: unfinished, not stored
        self.episodes.sort(key=lambda e: e[0], reverse=True)
        total, kept = 0, []
        for score, steps in self.episodes:  # best first, until the capacity is reached
            if kept and total + steps.batch_size[0] > self.capacity:
                break
            kept.append((score, steps))
            total += steps.batch_size[0]
        self.episodes = kept
        self.steps = torch.cat([td for _, td in kept]) if kept else None
        return added

    def sample(self, n: int, generator: torch.Generator) -> TensorDict:
        """``n`` steps drawn uniformly (with replacement) from the stored episodes."""
        if self.steps is None:
            raise ValueError("the self-imitation buffer is empty")
        return self.steps[torch.randint(self.steps.batch_size[0], (n,), generator=generator)]


def sil_loss(policy, critic, samples: TensorDict, value_coef: float) -> tuple[torch.Tensor, dict]:
    """``L_sil`` of the module docstring on ``samples`` (``SelfImitationBuffer.sample``); returns the loss and
    its parts for the log: the policy and value terms and the share of samples with R > V. ``policy``: the
    policy operator (trunk + policy head); ``critic``: the value head PPO's loss trains (it reads the
    trunk's features that ``policy`` writes, so the trunk runs once)."""
    inputs = samples.exclude("action", RETURN_KEY).clone()
    dist = policy.get_dist(inputs)  # also writes the trunk's features into inputs
    log_prob = dist.log_prob(samples["action"])  # (n,), summed over the action dimensions
    value = critic(inputs)["state_value"].reshape(-1)
    gap = (samples[RETURN_KEY] - value).clamp_min(0.0)  # (R - V)+
    policy_term = -(log_prob * gap.detach()).mean()
    value_term = 0.5 * gap.pow(2).mean()
    loss = policy_term + value_coef * value_term
    return loss, {"loss_sil": float(policy_term.detach()), "loss_sil_value": float(value_term.detach()),
                  "sil_positive": float((gap > 0).float().mean())}
