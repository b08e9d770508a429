"""Does the return follow success? The reward terms of successful and failed episodes, trained policies beside the expert.

    python benchmarks/rl/return_vs_success.py --task faucet \
        --policy runs/curriculum/faucet_state_dagger_wide_s0/checkpoint.pt runs/curriculum/faucet_state_dagger_wide_s1/checkpoint.pt \
        --json benchmarks/results/rl/return_vs_success_faucet.json

Why: PPO maximises the return, and the benchmark counts success. DexArt's reward pays, on an early success, a
terminal bonus of (horizon - t) * 1.2 * progress (progress: the part's |q| at that step, rad), so a policy can raise
its return by succeeding sooner or by flinging the part further in the step it succeeds, even if it then succeeds
less often. This script runs the scripted expert (with ``--expert-noise``, the demonstrations' executed-action noise,
so that it behaves like the clone PPO started from) and each checkpoint (deterministic, as evaluation) on the same
resets (``experts.solve.solve_episodes``: ``--episodes-per-object`` per object of ``--split``, from ``--seed``) and
records per episode: success, steps, the step of the first success, the part's |q| then, the return and the sum of
each named reward term. ``--reward`` names the reward every run is scored on (default DexArt's; ``capped``: the
terminal bonus counted up to the success threshold, envs/rewards.py), whatever reward a policy trained on: the reward
does not change what a policy observes, so policies trained on either compare on the same resets.

Written to ``--json``: task, split, reward, episodes_per_object, seed, expert_noise, policies (per policy: label, checkpoint,
frames, success_rate, mean_return, mean_return_success, mean_return_failure, mean_success_step, mean_q_at_success,
mean_bonus, terms: mean sum per episode of each reward term, and of the successes' and failures' alone), command,
machine.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.envs.rewards import REWARD_MODES
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.experts.solve import solve_episodes
from dexart_lite.rl.checkpoint import policy_function
from dexart_lite.rl.evaluate import load_policy
from dexart_lite.rollout import noisy, run_episodes
from dexart_lite.utils import check_choice, fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")


def episodes_of(policy, env, resets: list[tuple[int, str]]) -> list[dict]:
    """``run_episodes`` of ``policy`` with, per episode, the sum of each reward term and the step (and |q|) of the
    first success."""
    extra: list[dict] = []

    def on_reset(obs, info):
        extra.append({"terms": dict.fromkeys(info.get("reward_terms", {}), 0.0), "success_step": None, "q": None})

    def on_step(obs, action, reward, next_obs, info, t):
        row = extra[-1]
        for name, value in info["reward_terms"].items():
            row["terms"][name] = row["terms"].get(name, 0.0) + float(value)
        if info["success"] and row["success_step"] is None:
            row["success_step"], row["q"] = t + 1, abs(float(env.unwrapped.state.q))

    results = run_episodes(policy, env, resets, on_step=on_step, on_reset=on_reset, progress=not fast_mode())
    return [{**r, **e} for r, e in zip(results, extra)]


def summary(label: str, episodes: list[dict], checkpoint: str | None = None, frames: int | None = None) -> dict:
    """The means of ``episodes_of``'s rows (None where no episode qualifies)."""
    mean = lambda values: float(np.mean(values)) if len(values) else None  # noqa: E731
    wins, losses = [e for e in episodes if e["success"]], [e for e in episodes if not e["success"]]
    names = list(dict.fromkeys(n for e in episodes for n in e["terms"]))
    terms = {group: {n: mean([e["terms"].get(n, 0.0) for e in rows]) for n in names}
             for group, rows in (("all", episodes), ("success", wins), ("failure", losses))}
    return {"label": label, "checkpoint": checkpoint, "frames": frames, "episodes": len(episodes),
            "success_rate": mean([e["success"] for e in episodes]),
            "mean_return": mean([e["return"] for e in episodes]),
            "mean_return_success": mean([e["return"] for e in wins]),
            "mean_return_failure": mean([e["return"] for e in losses]),
            "mean_success_step": mean([e["success_step"] for e in wins]),
            "mean_q_at_success": mean([e["q"] for e in wins]),
            "mean_bonus": mean([e["terms"].get("bonus", 0.0) for e in wins]), "terms": terms}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    policy: list[str] = field(default_factory=list, metadata={"help": "checkpoints to compare with the expert"})
    expert_noise: float = field(default=0.1, metadata={"min": 0.0, "help": "the expert's executed-action noise std"})
    reward: str = field(default="dexart", metadata={"help": f"the reward the episodes are scored on: one of "
                                                            f"{', '.join(REWARD_MODES)}"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, task="faucet")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "split", episodes_per_object=5, seed=1000,
                    helps={"seed": "reset seeds: solve_episodes(seed)"})
    harness.options(parser, "json")
    args = parser.parse_args(argv)
    check_choice("reward", args.reward, REWARD_MODES)
    # the env each policy observes, without the reward it trained on (every run here is scored on --reward)
    loaded = [(path, actor_critic, cfg, {k: v for k, v in kwargs.items() if k != "reward"})
              for path, (actor_critic, cfg, kwargs) in ((p, load_policy(p)) for p in args.policy)]
    for path, _, cfg, _ in loaded:
        if cfg["task"] != args.task:
            raise ValueError(f"{path} was trained on {cfg['task']}, not {args.task}")
    env_kwargs = loaded[0][3] if loaded else {}
    env = make(args.task, split=args.split, point_noise=True, camera_noise=True, reward=args.reward, **env_kwargs)
    names = env.unwrapped.objects.names[:1] if fast_mode() else env.unwrapped.objects.names
    resets = solve_episodes(names, 1 if fast_mode() else args.episodes_per_object, args.seed)
    expert = noisy(ScriptedPolicy(env), args.expert_noise, np.random.default_rng(args.seed))
    rows = [summary(f"expert (noise {args.expert_noise:g})", episodes_of(expert, env, resets))]
    for path, actor_critic, cfg, kwargs in loaded:
        if kwargs != env_kwargs:
            raise ValueError(f"{path} observes {kwargs}, the first policy {env_kwargs}: compare one observation at a time")
        rows.append(summary(Path(path).parent.name, episodes_of(
            policy_function(actor_critic), env, resets), path, cfg["frames"]))
    env.close()
    result = {"task": args.task, "split": args.split, "reward": args.reward, "episodes_per_object": len(resets) // len(names),
              "seed": args.seed, "expert_noise": args.expert_noise, "policies": rows, **provenance(__file__, argv)}
    print("| policy | frames | success | return | return of successes | of failures | success step | |q| then | bonus |")
    print("|---|---|---|---|---|---|---|---|---|")
    fmt = lambda v, f=".2f": "-" if v is None else format(v, f)  # noqa: E731
    for r in rows:
        print(f"| {r['label']} | {r['frames'] or '-'} | {fmt(r['success_rate'])} | {fmt(r['mean_return'], '.0f')} "
              f"| {fmt(r['mean_return_success'], '.0f')} | {fmt(r['mean_return_failure'], '.0f')} "
              f"| {fmt(r['mean_success_step'], '.0f')} | {fmt(r['mean_q_at_success'])} | {fmt(r['mean_bonus'], '.0f')} |")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
