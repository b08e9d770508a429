"""The main job on defaults (what ``make demo`` runs): PPO on Laptop, evaluated on seen and unseen laptops.

    dexart-lite demo                      # about 8 minutes on 2 CPU cores (6 of them training)
    dexart-lite demo --minutes 30         # a longer training budget

It trains the small-PointNet policy with ``PRESETS["demo"]`` (the ``cpu`` preset: 4k frames per
batch, 5 epochs) until the time budget runs out, evaluates it with deterministic actions on the
seen (training) and unseen laptops, and writes into a fresh folder ``demo_out/<date-time>/``:

- ``report.md``: configuration, learning curve and the success table;
- ``learning_curve.png``: training return and success against frames;
- ``episode.gif``: one evaluation episode with the stage and reward on every frame;
- ``checkpoint.pt``: reload with ``dexart-lite eval --ckpt ...`` or train on with ``dexart-lite train --resume``.

A few minutes of PPO is far too short to open a laptop (DexArt trains ~15M frames); the demo shows
the whole pipeline and the starting point. ``benchmarks/bench_learning.py`` is the long run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dexart_lite.rl import ppo
from dexart_lite.utils import fast_mode


def demo_config(out: Path, minutes: float | None = None):
    """``PRESETS["demo"]`` writing to ``out``; in fast mode (tests) a run of a few hundred frames."""
    overrides = {"out": str(out)}
    if minutes is not None:
        overrides["max_minutes"] = minutes
    if fast_mode():
        overrides.update(frames=800, frames_per_batch=400, minibatch=200, epochs=1, num_points=64,
                         max_episode_steps=20, eval_episodes=1, progress=False)
    return ppo.preset("demo", **overrides)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path(ppo.PRESETS["demo"]["out"]),
                        help="parent folder; each demo writes a new <date-time> folder inside it")
    parser.add_argument("--minutes", type=float, default=None,
                        help=f"training time budget (default {ppo.PRESETS['demo']['max_minutes']})")


def run(args: argparse.Namespace) -> int:
    if args.minutes is not None and args.minutes <= 0:
        raise ValueError(f"--minutes must be > 0, got {args.minutes}")
    out = args.out / time.strftime("%Y%m%d-%H%M%S")
    while out.exists():  # two demos in the same second: never reuse a folder
        out = out.with_name(out.name + "_")
    cfg = demo_config(out, args.minutes)
    print(f"dexart-lite demo: PPO on {cfg.task} ({cfg.encoder} PointNet) for up to {cfg.max_minutes:g} min, "
          f"then {cfg.eval_episodes} evaluation episodes per seen and unseen object -> {out}")
    start = time.perf_counter()
    result = ppo.train(cfg)
    print(f"\ndone in {(time.perf_counter() - start) / 60:.1f} min, {result['frames']:,} training frames")
    for split, res in result["eval"].items():
        print(f"  {split:6s} success {res['success_rate']:.2f}, mean stage reached {res['mean_max_stage']:.2f} "
              f"({res['episodes']} episodes)")
    print(f"report:     {result['report']}\ncurve:      {result['curve']}\nepisode:    {result['gif']}\n"
          f"checkpoint: {result['checkpoint']}")
    return 0
