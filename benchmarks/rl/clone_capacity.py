"""Can the PPO actor clone the scripted expert? Behaviour cloning + DAgger with the actor-critic of ``dexart-lite
train``, per network width, on the state-only observation; success from the true reset.

    python benchmarks/rl/clone_capacity.py --task laptop --arch dexart wide --seeds 0 1 --jobs 2

The warm start of the curriculum recipes (``warmstart.clone_the_guide``: ``--demo-episodes`` noisy expert episodes
per training object, ``--bc-warmstart`` epochs of MSE on their clean labels with inputs normalised from them,
then ``--dagger-rounds`` in which the clone drives and the expert labels what it visits) on networks of two
sizes: ``dexart`` is DexArt's (a 64-unit state MLP in the trunk, 64x64 policy and value heads), ``wide`` a
256-unit state MLP and 256x256 heads (the size of ``benchmarks/students/state_student.py``'s MLP, which imitates the
expert well). What PPO then starts from is what this measures: a clone that fails from the true reset leaves
PPO nothing to keep.

Written to ``benchmarks/results/rl/curriculum/clone_capacity_<task>_<obs>.json``: per (arch, seed) the DAgger
rounds' own success (the clone driving), the final clone's seen / unseen success (deterministic, from the true
reset, ``--eval-episodes`` per object, env seed 100 as ``dexart-lite eval``), the sample count and wall time;
the command and the machine.
"""

from __future__ import annotations

import argparse
import functools
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch

from dexart_lite.cli import add_config_arguments
from dexart_lite.models.actor_critic import make_actor_critic
from dexart_lite.rl import ppo
from dexart_lite.rl.checkpoint import network_encoder
from dexart_lite.rl.env import env_dims, make_env
from dexart_lite.rl.evaluate import evaluate
from dexart_lite.rl.warmstart import clone_the_guide
from dexart_lite.utils import benchmark_results, fast_mode, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__) / "curriculum"
harness = sibling_script(__file__, "_harness")
ARCHS = {"dexart": {"head": "64,64", "state_hidden": 64}, "wide": {"head": "256,256", "state_hidden": 256}}


def clone(task: str, obs: str, arch: str, seed: int, demo_episodes: int, demo_noise: float, epochs: int, rounds: int,
          eval_episodes: int) -> dict:
    """One clone: demonstrations, warm start, DAgger rounds, evaluation on both splits."""
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    start = time.perf_counter()
    cfg = ppo.preset("fast", task=task, obs=obs, seed=seed, demo_episodes=demo_episodes,
                     demo_noise=demo_noise, bc_warmstart=epochs, dagger_rounds=rounds, **ARCHS[arch])
    if fast_mode():  # a smoke run of the script itself, not evidence
        cfg = replace(cfg, max_episode_steps=20, num_points=64, demo_episodes=1, bc_warmstart=1,
                                      dagger_rounds=min(rounds, 1))
    probe = make_env(task, **cfg.env_kwargs())
    _, state_dim, action_dim = env_dims(probe)
    probe.close()
    actor_critic = make_actor_critic(state_dim, action_dim, network_encoder(asdict(cfg)), cfg.init_log_std,
                                     head=cfg.head_widths(), normalize=True, state_hidden=cfg.state_hidden)
    samples, info = clone_the_guide(cfg, actor_critic)
    episodes = 1 if fast_mode() else eval_episodes
    success = {split: evaluate(actor_critic, task, split, episodes, 100, cfg.env_kwargs())["success_rate"]
               for split in ("seen", "unseen")}
    return {"arch": arch, **ARCHS[arch], "seed": seed, "samples": int(len(samples)),
            "guide_success": info["guide_success"], "dagger_success": info["dagger_success"],
            "final_loss": info["warmstart_loss"][-1], "seen_success": success["seen"],
            "unseen_success": success["unseen"], "wall_time_s": round(time.perf_counter() - start, 1)}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    arch: list[str] = field(default_factory=lambda: list(ARCHS),
                            metadata={"choices": list(ARCHS), "help": "the clone architectures, one run each"})
    rounds: int = field(default=3, metadata={"min": 0, "help": "DAgger rounds"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", "obs")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, seeds=[0, 1])
    add_config_arguments(parser, ppo.PPOConfig, names=["demo_episodes", "demo_noise"], overrides=False,
                         defaults={"demo_episodes": 4, "demo_noise": 0.1})
    harness.options(parser, "eval_episodes", "json", epochs=50,
                    helps={"epochs": "BC epochs after the demos and after each round"})
    harness.options(parser, "jobs", helps={"jobs": "clones trained at once (one process each)"})
    args = parser.parse_args(argv)
    start = time.perf_counter()
    grid = [{"arch": arch, "seed": seed} for arch in args.arch for seed in args.seeds]
    settings = {k: getattr(args, k) for k in ("task", "obs", "demo_episodes", "demo_noise", "epochs", "rounds",
                                              "eval_episodes")}
    rows = list(harness.each(functools.partial(clone, **settings), grid, jobs=args.jobs, desc="clones"))
    summary = {arch: {split: float(np.mean([r[f"{split}_success"] for r in rows if r["arch"] == arch]))
                      for split in ("seen", "unseen")} for arch in args.arch}
    result = {"task": args.task, "obs": args.obs, "demo_episodes": args.demo_episodes, "demo_noise": args.demo_noise,
              "epochs": args.epochs, "rounds": args.rounds, "eval_episodes_per_object": args.eval_episodes,
              "eval_seed": 100, "per_run": rows, "summary": summary, "jobs": args.jobs,
              "wall_time_s": round(time.perf_counter() - start, 1),
              **provenance(__file__, argv)}
    path = args.json or RESULTS / f"clone_capacity_{args.task}_{args.obs}.json"
    if not fast_mode() or args.json:
        write_json(path, result)
    for arch, s in summary.items():
        print(f"{arch}: seen {s['seen']:.2f} unseen {s['unseen']:.2f}")
    return result


if __name__ == "__main__":
    main()
