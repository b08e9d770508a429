"""How often each expert succeeds over a split (the committed ``benchmarks/results/experts/solve_*.json``), and
``dexart-lite solve``.

    dexart-lite solve --task laptop --split seen --episodes-per-object 3 --json laptop.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

import dexart_lite
from dexart_lite import objects as objects_lib
from dexart_lite.experts import SOLVERS, ScriptedPolicy, SynergyScriptedPolicy
from dexart_lite.rollout import NOISE_PARTS, noisy, run_episodes
from dexart_lite.utils import check_choice


def solve_episodes(names: list[str], episodes_per_object: int, seed: int) -> list[tuple[int, str]]:
    """``(reset seed, object)`` of every episode of ``solve``, in its order: episode ``k`` of object ``i``
    is reset with seed ``seed + 1000 k + i``."""
    return [(seed + 1000 * k + i, name) for k in range(episodes_per_object) for i, name in enumerate(names)]


def solve(task: str, split: str = "seen", episodes_per_object: int = 3, seed: int = 0, object_names=None,
          progress: bool = True, action_noise: float = 0.0, env_kwargs: dict | None = None,
          expert: str | None = None, noise_part: str = "all") -> dict:
    """Run the expert over every object of a split; success counts if reached at any step.

    Episode ``k`` of object ``i`` is reset with seed ``seed + 1000 k + i``. ``action_noise``: std of
    Gaussian noise added to every action dimension before the env's clip to [-1, 1], as PPO's sampled
    actions (``benchmarks/experts/exploration_noise.py``); drawn from an RNG seeded with ``seed``, separate
    from the env's. ``env_kwargs``: further keywords of the env (e.g. ``solver_iterations``, for
    ``benchmarks/perf/bench_physics.py``; ``hand="synergy"``: the expert's hand projected on the synergies).
    ``expert``: another expert of the task than its own, by class name (``dexart_lite.experts.TASK_EXPERTS``).
    ``noise_part``: the action dimensions the noise perturbs (``rollout.NOISE_PARTS``: ``all``, ``arm``: the palm
    twist only, ``hand``: the 16 joint targets only).
    """
    from dexart_lite.envs import make

    if not (math.isfinite(action_noise) and action_noise >= 0.0):
        raise ValueError(f"action_noise must be a finite std >= 0, got {action_noise}")
    check_choice("noise part", noise_part, NOISE_PARTS)  # before the env is built
    env = make(task, split=split, object_names=object_names, **{"num_points": 32, **(env_kwargs or {})})
    names = env.unwrapped.objects.names
    expert_cls = SynergyScriptedPolicy if env.unwrapped.hand_mode == "synergy" else ScriptedPolicy
    policy = noisy(expert_cls(env, expert), action_noise, np.random.default_rng(seed), noise_part)
    episodes = solve_episodes(names, episodes_per_object, seed)
    results = run_episodes(policy, env, episodes, progress=progress, desc=f"solve {task}/{split}")
    env.close()
    rates = {n: float(np.mean([e["success"] for e in results if e["object"] == n])) for n in names}
    stage_steps = np.bincount(np.concatenate([e["stages"] for e in results]) - 1, minlength=3)  # steps in stage 1..3
    return {"task": task, "split": split, "episodes_per_object": episodes_per_object, "seed": seed,
            "expert": policy.policy.expert.__name__,
            "action_noise": action_noise, **({"noise_part": noise_part} if noise_part != "all" else {}),
            "success_rate": float(np.mean([e["success"] for e in results])),
            "success_per_object": rates, "mean_max_stage": float(np.mean([e["max_stage"] for e in results])),
            "mean_return": float(np.mean([e["return"] for e in results])),
            "stage_fractions": {f"stage{s + 1}": float(f) for s, f in enumerate(stage_steps / stage_steps.sum())}}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, help=f"one of {', '.join(SOLVERS)}")
    parser.add_argument("--split", default="seen", help=f"one of {', '.join(objects_lib.SPLITS)}")
    parser.add_argument("--episodes-per-object", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--expert", help="another expert's class name than the task's own (e.g. BucketSolver, the "
                        "bucket's fingertip hook)")
    parser.add_argument("--json", type=Path, help="write the results here")


def run(args: argparse.Namespace) -> int:
    check_choice("task", args.task, dexart_lite.TASKS)
    result = solve(args.task, args.split, args.episodes_per_object, args.seed, expert=args.expert)
    print("| object | success |\n|---|---|")
    for name, rate in result["success_per_object"].items():
        print(f"| {name} | {rate:.2f} |")
    print(f"| **all** | **{result['success_rate']:.2f}** |  (mean max stage {result['mean_max_stage']:.2f})")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0
