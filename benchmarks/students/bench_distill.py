"""Distilled students: the scripted expert -> a point-cloud student (DAgger or BC), over seeds.

    python benchmarks/students/bench_distill.py --task laptop --method dagger --seeds 0 1 --json benchmarks/results/students/distill_laptop.json

Each seed is one ``dexart-lite distill`` run with the defaults of ``DistillConfig`` (small PointNet)
into ``runs/distill_<task>_<method>_s<seed>``; a seed whose folder already holds ``eval_unseen.json``
from the same settings is read back instead of run again (an interrupted study resumes). The seeds
run one after the other, alone, so each ``wall_time_s`` is the run's own on this machine.
A variant changes some fields and names its run folders::

    python benchmarks/students/bench_distill.py --task laptop --variant novel --set drop_state=time,palm_velocity \
        --json benchmarks/results/students/distill_laptop_novel.json

Writes ``task``, ``method``, ``seeds``, ``seen_success`` / ``unseen_success`` (means over seeds),
``per_seed`` (success, mean stage, frames, wall time, the per-round log), ``expert_frames``,
``student_frames``, ``wall_time_s`` (per seed), ``eval_episodes_per_object``, ``command`` and
``machine``, and a PNG next to the JSON (success per DAgger round, every seed). These are distilled
students, not reinforcement learning: compare them with DexArt's RL numbers only as a reference.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import dexart_lite
from dexart_lite.experts import SOLVERS
from dexart_lite.imitation.distill import DistillConfig
from dexart_lite.study import run_arm
from dexart_lite.cli import add_config_arguments
from dexart_lite.utils import (benchmark_results, fast_mode, parse_overrides, provenance, save_figure, sibling_script,
                               write_json)

harness = sibling_script(__file__, "_harness")

RESULTS = benchmark_results(__file__)
# DexArt Table 2, PPO without pre-training, success seen / unseen (mean over 3 seeds), for reference only
PAPER_RL_NO_PRETRAIN = {"faucet": (0.30, 0.28), "bucket": (0.51, 0.56), "laptop": (0.81, 0.41), "toilet": (0.71, 0.46)}


def run_seed(cfg: DistillConfig) -> dict:
    """One seed through ``study.run_arm``: trained, or read back when its folder holds a finished run with the same
    settings."""
    result = run_arm(cfg)
    if result["resumed"]:
        print(f"{cfg.out}: finished before, read back")
    print(f"seed {cfg.seed}: seen {result['seen_success']:.2f}, unseen {result['unseen_success']:.2f}, "
          f"{result['wall_time_s'] / 60:.1f} min")
    return {"seed": cfg.seed, **result}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    variant: str = field(default="", metadata={"help": "a name for --set, in the run folders "
                                                       "(distill_<task>_<method>_<variant>_s<seed>)"})
    collect: list[Path] | None = field(default=None, metadata={"help": "summarise these finished `dexart-lite distill` "
                                       "folders instead of running seeds"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, DistillConfig, names=["task", "method", "encoder"])  # and --set FIELD=VALUE ...
    harness.options(parser, "runs", seeds=[0, 1, 2], jobs=1,
                    helps={"jobs": "seeds at once (1: each seed alone, so its wall_time_s is its own)"})
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, helps={"json": "default benchmarks/results/students/distill_<task>.json"}, json=None)
    args = parser.parse_args(argv)
    if args.collect:
        return collect(args, argv)
    path = args.json or RESULTS / f"distill_{args.task}.json"
    requested = parse_overrides(args.overrides, DistillConfig)
    overrides = dict(requested)  # plus the smoke-run settings in fast mode
    if requested and not args.variant:
        raise ValueError("--set needs a --variant name (its runs must not mix with the defaults' folders)")
    if fast_mode():  # a smoke run of the script itself, not evidence
        overrides.update(num_points=32, max_episode_steps=10, demo_episodes_per_object=1, rounds=1,
                         episodes_per_round=1, epochs=1, epochs_per_round=1, eval_episodes=1, progress=False,
                         threads=1, objects=dexart_lite.objects.list_objects(args.task, "seen")[0].name)
        if args.json is None:  # never overwrite the committed evidence with a smoke run
            path = args.runs / "bench_distill_fast.json"

    def config(seed: int) -> DistillConfig:
        folder = "_".join(filter(None, ("distill", args.task, args.method, args.variant, f"s{seed}")))
        return DistillConfig(task=args.task, method=args.method, encoder=args.encoder, seed=seed,
                             out=str(args.runs / folder), **overrides)

    per_seed = list(harness.each(run_seed, [{"cfg": config(seed)} for seed in args.seeds], jobs=args.jobs,
                                 desc="seeds"))
    result = summary(per_seed, args.task, args.method, args.encoder, argv)
    result["variant"], result["overrides"] = args.variant, requested
    result["expert"] = SOLVERS[args.task].__name__  # the teacher: the task's expert when the study ran
    write_json(path, result)
    plot(per_seed, path.with_suffix(".png"), f"{args.method} on {args.task} ({args.encoder} PointNet)")
    print(f"{args.task} {args.method}: seen {result['seen_success']:.2f} +- {result['seen_success_std']:.2f}, "
          f"unseen {result['unseen_success']:.2f} +- {result['unseen_success_std']:.2f}; wrote {path}")
    return result


def collect(args, argv) -> dict:
    """The JSON and PNG of ``main`` from finished run folders (each holds checkpoint.pt, eval_*.json)."""
    from dexart_lite.rl.checkpoint import load_checkpoint

    per_seed = []
    for run in args.collect:
        payload = load_checkpoint(run / "checkpoint.pt")
        evals = {split: json.loads((run / f"eval_{split}.json").read_text()) for split in ("seen", "unseen")}
        history = payload["history"]
        per_seed.append({"seed": payload["config"]["seed"], "run": str(run), "config": payload["config"],
                         "seen_success": evals["seen"]["success_rate"], "unseen_success": evals["unseen"]["success_rate"],
                         "mean_max_stage": {s: e["mean_max_stage"] for s, e in evals.items()},
                         "expert_frames": history[-1]["expert_frames"], "student_frames": history[-1]["student_frames"],
                         "wall_time_s": history[-1]["wall_s"], "history": history})
    cfg = per_seed[0]["config"]
    path = args.json or RESULTS / f"distill_{cfg['task']}.json"
    result = summary(per_seed, cfg["task"], cfg["method"], cfg["encoder"], argv)
    result["wall_time_note"] = "wall_time_s: training and collection, up to the last round (evaluation not included)"
    write_json(path, result)
    plot(per_seed, path.with_suffix(".png"), f"{cfg['method']} on {cfg['task']} ({cfg['encoder']} PointNet)")
    print(f"wrote {path}")
    return result


def summary(per_seed: list[dict], task: str, method: str, encoder: str, argv) -> dict:
    mean = lambda key: float(np.mean([r[key] for r in per_seed]))  # noqa: E731
    std = lambda key: float(np.std([r[key] for r in per_seed]))  # noqa: E731
    return {"task": task, "method": method, "encoder": encoder, "seeds": [r["seed"] for r in per_seed],
            "seen_success": mean("seen_success"), "unseen_success": mean("unseen_success"),
            "seen_success_std": std("seen_success"), "unseen_success_std": std("unseen_success"),
            "expert_frames": [r["expert_frames"] for r in per_seed],
            "student_frames": [r["student_frames"] for r in per_seed],
            "wall_time_s": [round(r["wall_time_s"], 1) for r in per_seed],
            "eval_episodes_per_object": per_seed[0]["config"]["eval_episodes"],
            "paper_rl_no_pretrain": dict(zip(("seen", "unseen"), PAPER_RL_NO_PRETRAIN[task])),
            "per_seed": per_seed, **provenance(__file__, argv),
            "note": "distilled students (privileged scripted expert -> point-cloud policy), not RL"}


def plot(per_seed: list[dict], path: Path, title: str) -> None:
    """Success of the episodes collected in each round (beta-mixed in DAgger rounds), per seed,
    with the final deterministic evaluation as the last points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.4))
    for r in per_seed:
        frames = [h["frames"] for h in r["history"]]
        line, = ax.plot(frames, [h["collect_success"] for h in r["history"]], marker="o", alpha=0.7,
                        label=f"seed {r['seed']}: collection (beta-mixed)")
        ax.scatter([frames[-1]] * 2, [r["seen_success"], r["unseen_success"]], marker="*", s=90,
                   color=line.get_color(), zorder=3)
    ax.set(xlabel="frames (expert + student)", ylabel="success rate", ylim=(-0.05, 1.05), title=title)
    ax.text(0.01, 0.02, "stars: final student alone, seen and unseen", transform=ax.transAxes, fontsize=8)
    ax.legend(fontsize=7)
    save_figure(fig, path, dpi=120)


if __name__ == "__main__":
    main()
