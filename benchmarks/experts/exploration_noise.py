"""How much exploration noise can a policy that knows the answer tolerate? (a diagnosis of slow PPO)

PPO starts with a Gaussian policy of standard deviation 1 on all 22 action dimensions (DexArt: initial
``log_std`` 0) and, with no entropy bonus, shrinks it only through the policy gradient; the 1M-frame
Laptop run ended at std 0.97. This script runs the scripted solver (``dexart_lite.experts``, which
uses the privileged object state) with the same kind of noise, Gaussian of std ``sigma`` added to each
action before the env's clip, and reports success, the stage reached, the fraction of steps per stage
and the return for each ``sigma``. If even the scripted solver fails at ``sigma`` = 1, PPO's exploration
hardly ever shows it a rewarded manipulation step, whatever its network has learnt.

    python benchmarks/experts/exploration_noise.py --task laptop --splits seen unseen --episodes-per-object 3 \\
        --sigmas 0 0.3 0.5 --json benchmarks/results/experts/exploration_noise_laptop.json

The same curve says how imitable an expert is: a student's actions are the expert's plus an error,
so an expert whose success survives noise can be copied by an imperfect student (the distillation
issue's bar: >= 0.9 at std 0.3 and >= 0.7 at 0.5 on both splits).

Writes the JSON (one row per split, ``sigma`` and seed; ``mean_over_seeds``: their mean) and a PNG
next to it (success and mean return against ``sigma``, one line per split, means over the seeds).
"""

from __future__ import annotations

import argparse
import functools
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.objects import list_objects
from dexart_lite.experts import SOLVERS
from dexart_lite.experts.solve import solve
from dexart_lite.rollout import NOISE_PARTS
from dexart_lite.utils import fast_mode, provenance, save_figure, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

SIGMAS = (0.0, 0.1, 0.3, 0.5, 1.0)


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    noise_part: str = field(default="all", metadata={"choices": list(NOISE_PARTS), "help": "the action dimensions "
                            "perturbed: all, arm (the palm twist) or hand (the joint targets)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", "jobs", splits=["seen"], episodes_per_object=2, seeds=[0],
                    helps={"seeds": "one solve per seed (its own reset seeds and noise draws); the table adds their "
                                    "mean", "json": "write the results here (and the PNG next to it); a run stopped "
                                    "half-way continues from it"})
    harness.options(parser, "expert", sigmas=list(SIGMAS))
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "json")
    args = parser.parse_args(argv)
    if fast_mode():  # a smoke run of the script itself, not evidence
        args.sigmas, args.episodes_per_object = [0.0, 1.0], 1

    grid = [{"split": split, "action_noise": sigma, "seed": seed}
            for split in args.splits for sigma in args.sigmas for seed in args.seeds]
    settings = {"task": args.task, "expert": args.expert, "noise_part": args.noise_part,
                "episodes_per_object": args.episodes_per_object, "fast": fast_mode()}
    rows = harness.run_grid(functools.partial(measure, args.task, args.episodes_per_object, args.expert,
                                              args.noise_part), grid, jobs=args.jobs, path=args.json,
                            settings=settings, desc="solves")
    summary = mean_over_seeds(rows)

    print(f"| split | noise std | seed | success ({args.task}) | mean max stage | steps in stage 1 / 2 / 3 "
          "| mean return |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        f = r["stage_fractions"]
        print(f"| {r['split']} | {r['action_noise']:g} | {r['seed']} | {r['success_rate']:.2f} | "
              f"{r['mean_max_stage']:.2f} | {f['stage1']:.2f} / {f['stage2']:.2f} / {f['stage3']:.2f} | "
              f"{r['mean_return']:.1f} |")
    if len(args.seeds) > 1:
        for r in summary:
            print(f"| {r['split']} | {r['action_noise']:g} | mean | **{r['success_rate']:.2f}** +- "
                  f"{r['success_std']:.2f} | {r['mean_max_stage']:.2f} | | {r['mean_return']:.1f} |")
    result = {"task": args.task, "expert": rows[0]["expert"], "noise_part": args.noise_part, "splits": args.splits,
              "episodes_per_object": args.episodes_per_object, "seeds": args.seeds, "rows": rows,
              "mean_over_seeds": summary, "settings": settings, **provenance(__file__, argv)}
    if args.json:
        write_json(args.json, result)
        plot(summary, args.json.with_suffix(".png"), f"{args.task} ({rows[0]['expert']}) + Gaussian action noise")
        print(f"wrote {args.json} and {args.json.with_suffix('.png')}")
    return result


def measure(task: str, episodes_per_object: int, expert: str | None, noise_part: str, split: str,
            action_noise: float, seed: int) -> dict:
    """One solve of ``split`` at noise std ``action_noise`` and ``seed`` (fast mode: its first object alone)."""
    object_names = [list_objects(task, split)[0].name] if fast_mode() else None
    start = time.perf_counter()
    res = solve(task, split, episodes_per_object, seed, object_names=object_names, progress=not fast_mode(),
                action_noise=action_noise, expert=expert, noise_part=noise_part)
    return {**res, "wall_time_s": time.perf_counter() - start}


def mean_over_seeds(rows: list[dict]) -> list[dict]:
    """One row per split and ``sigma``: success (mean and std over the seeds), mean max stage and return."""
    out = []
    for key in dict.fromkeys((r["split"], r["action_noise"]) for r in rows):
        mine = [r for r in rows if (r["split"], r["action_noise"]) == key]
        rates = np.array([r["success_rate"] for r in mine])
        out.append({"split": key[0], "action_noise": key[1], "seeds": [r["seed"] for r in mine],
                    "success_rate": float(rates.mean()), "success_std": float(rates.std()),
                    "mean_max_stage": float(np.mean([r["mean_max_stage"] for r in mine])),
                    "mean_return": float(np.mean([r["mean_return"] for r in mine]))})
    return out


def plot(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_success, ax_return) = plt.subplots(1, 2, figsize=(9, 3.2))
    for split in dict.fromkeys(r["split"] for r in rows):
        mine = [r for r in rows if r["split"] == split]
        sigmas = [r["action_noise"] for r in mine]
        ax_success.plot(sigmas, [r["success_rate"] for r in mine], marker="o", label=f"success, {split}")
        ax_return.plot(sigmas, [r["mean_return"] for r in mine], marker="o", label=split)
    ax_success.set(xlabel="action noise std", ylabel="success rate", ylim=(-0.05, 1.05), title=title)
    ax_success.legend()
    ax_return.legend()
    ax_return.set(xlabel="action noise std", ylabel="mean episode return")
    save_figure(fig, path)


if __name__ == "__main__":
    main()
