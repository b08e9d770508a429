"""Learning evidence: one real PPO run, evaluated on seen and unseen objects, with its curve.

    python benchmarks/rl/bench_learning.py --task laptop --frames 1000000
    python benchmarks/rl/bench_learning.py --task laptop --frames 1000000 --resume   # continue an interrupted run
    python benchmarks/rl/bench_learning.py --task laptop --preset cpu --tag state_shaped_s0 \
        --set obs=state reward=shaped lr=3e-4 reward_scale=0.01 --init-log-std -1.2 --frames 300000

Trains with ``dexart_lite.rl.ppo.train`` (the faithful preset unless ``--preset cpu``) into
``--out`` (default ``runs/learning_<task>``), then writes ``benchmarks/results/rl/learning_<task>.json``
(frames, seen_success, unseen_success, wall_time_s, command, machine, the curve's points and the
details) and copies the learning curve to ``benchmarks/results/rl/learning_<task>.png``; ``--tag T``
names them ``learning_<task>_T.*`` instead (e.g. the encoder-size ablation of tutorial 04). The original paper's numbers
without pretraining are stored beside ours for comparison (DexArt Table 2; the curves of Fig. 6-8
stop at about 10M / 40M / 15M / 8M frames for faucet / bucket / laptop / toilet).
"""

from __future__ import annotations

import argparse
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl import ppo
from dexart_lite.utils import benchmark_results, fast_mode, parse_overrides, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")
RESULTS = benchmark_results(__file__)
# DexArt Table 2, no pre-training, success seen / unseen (mean over 3 seeds)
PAPER_NO_PRETRAIN = {"faucet": (0.30, 0.28), "bucket": (0.51, 0.56), "laptop": (0.81, 0.41), "toilet": (0.71, 0.46)}
PAPER_FRAMES = {"faucet": 10e6, "bucket": 40e6, "laptop": 15e6, "toilet": 8e6}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    preset: str = field(default="faithful", metadata={"choices": list(ppo.PRESETS), "help": "the PPO preset"})
    out: Path | None = field(default=None, metadata={"help": "training folder (None: runs/learning_<task>)"})
    tag: str = field(default="", metadata={"help": "suffix of the result names: learning_<task>_<tag>.json (needed "
                                                   "by --set)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, ppo.PPOConfig, names=["task", "frames", "encoder", "workers", "seed", "eval_episodes",
                                                       "init_log_std", "resume"], defaults={"init_log_std": None},
                         helps={"init_log_std": "initial log std of the actions (None: the preset's; DexArt: 0)"})
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, results=RESULTS)
    args = parser.parse_args(argv)
    name = f"learning_{args.task}" + (f"_{args.tag}" if args.tag else "")
    out = args.out or Path("runs") / name
    requested = parse_overrides(args.overrides, ppo.PPOConfig)
    if requested and not args.tag:
        raise ValueError("--set needs a --tag (its results must not overwrite the defaults' learning_<task>.json)")
    overrides = dict(requested)
    if fast_mode():  # a smoke run of the script itself, not evidence
        overrides.update(frames_per_batch=400, minibatch=200, epochs=1, num_points=64, max_episode_steps=20)
        args.frames, args.eval_episodes = min(args.frames, 800), 1
        if args.results == RESULTS:  # never overwrite the committed evidence with a smoke run
            args.results = out / "results"
    fields = dict(task=args.task, frames=args.frames, encoder=args.encoder, workers=args.workers, seed=args.seed,
                  eval_episodes=args.eval_episodes, out=str(out), resume=args.resume, progress=not fast_mode())
    if args.init_log_std is not None:
        fields["init_log_std"] = args.init_log_std
    clash = sorted(set(requested) & set(fields))
    if clash:
        raise ValueError(f"--set {', '.join(clash)}: use the script's own option(s) instead")
    cfg = ppo.preset(args.preset, **{**fields, **overrides})
    result = ppo.train(cfg)

    args.results.mkdir(parents=True, exist_ok=True)
    curve = args.results / f"{name}.png"
    shutil.copyfile(result["curve"], curve)
    seen, unseen = result["eval"]["seen"], result["eval"]["unseen"]
    history = result["history"]
    summary = {
        "task": args.task, "frames": result["frames"],
        "seen_success": seen["success_rate"], "unseen_success": unseen["success_rate"],
        "seen_mean_max_stage": seen["mean_max_stage"], "unseen_mean_max_stage": unseen["mean_max_stage"],
        "wall_time_s": history[-1]["wall_s"] if history else 0.0,
        "wall_time_with_eval_s": result["wall_time_s"],
        "eval_episodes_per_object": args.eval_episodes, "eval_seed": cfg.eval_seed,
        "paper_no_pretraining": {"seen": PAPER_NO_PRETRAIN[args.task][0], "unseen": PAPER_NO_PRETRAIN[args.task][1],
                                 "frames": PAPER_FRAMES[args.task]},
        "collect_fps": result["frames"] / max(sum(h["collect_s"] for h in history), 1e-9),
        "update_fps": result["frames"] / max(sum(h["update_s"] for h in history), 1e-9),
        "curve": curve.name, "preset": args.preset, "departures_from_preset": requested, "config": {k: v for k, v in vars(cfg).items()},
        "curve_points": [{k: h[k] for k in ("frames", "episode_return", "success_rate", "stage3_frac", "wall_s")}
                         for h in history],
        "last_batches": history[-3:], "seen": seen, "unseen": unseen,
        **provenance(__file__, argv),
    }
    path = args.results / f"{name}.json"
    write_json(path, summary)
    print(f"| {args.task} | frames | seen | unseen |\n|---|---|---|---|")
    print(f"| dexart_lite ({args.preset}) | {result['frames']:,} | {seen['success_rate']:.2f} | {unseen['success_rate']:.2f} |")
    paper = PAPER_NO_PRETRAIN[args.task]
    print(f"| DexArt paper, no pretraining | ~{PAPER_FRAMES[args.task] / 1e6:.0f}M | {paper[0]:.2f} | {paper[1]:.2f} |")
    print(f"wrote {path} and {curve}")
    return summary


if __name__ == "__main__":
    main()
