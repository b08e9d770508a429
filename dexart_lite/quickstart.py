"""The main job on defaults (what ``make demo`` runs): a point-cloud policy that opens laptops, seen and unseen.

    dexart-lite demo                      # about 7 minutes on 2 CPU cores
    dexart-lite demo --minutes 15         # a longer distillation budget

It distils the scripted laptop expert (``experts.FeedbackLidSolver``, which reads the simulator)
into the small-PointNet PPO actor-critic, which sees only the point cloud and the robot's state:
expert demonstrations with noise on the executed actions, behaviour cloning, then DAgger rounds in
which the student drives and the expert labels every state it visits, until the time budget is
spent (``DEMO``). Then it evaluates the student with deterministic actions on the seen (training)
and the unseen laptops and writes into a fresh folder ``demo_out/<date-time>/``:

- ``report.md``: configuration, the rounds and the success table;
- ``rounds.png``: success of each round's episodes and of the final student;
- ``episode.gif``: the student on an unseen laptop, with the stage and reward on every frame;
- ``eval_seen.json``, ``eval_unseen.json``: the evaluation (``success_rate`` per object and overall);
- ``checkpoint.pt``: a PPO checkpoint (``dexart-lite eval --ckpt ...``).

This is imitation of a privileged expert, not reinforcement learning: ``dexart-lite train`` is PPO
(far too slow to open a laptop in minutes on a CPU; see docs/results/ppo.md).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dexart_lite.imitation.distill import DistillConfig, distill
from dexart_lite.utils import fast_mode

# The demo's distillation: DistillConfig's defaults with a time budget and a shorter evaluation.
DEMO = {"task": "laptop", "method": "dagger", "encoder": "small", "max_minutes": 6.0, "eval_episodes": 2,
        "gif": True}
OUT = Path("demo_out")


def demo_config(out: Path, minutes: float | None = None) -> DistillConfig:
    """``DEMO`` writing to ``out``; in fast mode (tests) a run of a few dozen frames."""
    overrides = {**DEMO, "out": str(out)}
    if minutes is not None:
        overrides["max_minutes"] = minutes
    if fast_mode():
        overrides.update(num_points=32, max_episode_steps=12, demo_episodes_per_object=1, rounds=1,
                         episodes_per_round=1, epochs=1, epochs_per_round=1, eval_episodes=1, progress=False,
                         objects="laptop_11cbb00f39", threads=1)
    return DistillConfig(**overrides)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=OUT,
                        help="parent folder; each demo writes a new <date-time> folder inside it")
    parser.add_argument("--minutes", type=float, default=None,
                        help=f"distillation time budget (default {DEMO['max_minutes']:g})")


def run(args: argparse.Namespace) -> int:
    if args.minutes is not None and args.minutes <= 0:
        raise ValueError(f"--minutes must be > 0, got {args.minutes}")
    out = args.out / time.strftime("%Y%m%d-%H%M%S")
    while out.exists():  # two demos in the same second: never reuse a folder
        out = out.with_name(out.name + "_")
    cfg = demo_config(out, args.minutes)
    print(f"dexart-lite demo: distil the scripted {cfg.task} expert into a {cfg.encoder}-PointNet student "
          f"(DAgger, {cfg.max_minutes:g} min budget), then {cfg.eval_episodes} evaluation episodes per seen "
          f"and unseen object -> {out}")
    start = time.perf_counter()
    result = distill(cfg)
    print(f"\ndone in {(time.perf_counter() - start) / 60:.1f} min: {result['expert_frames']:,} expert frames, "
          f"{result['student_frames']:,} student frames")
    for split, res in result["eval"].items():
        print(f"  {split:6s} success {res['success_rate']:.2f}, mean stage reached {res['mean_max_stage']:.2f} "
              f"({res['episodes']} episodes)")
    print(f"report:     {result['report']}\ncurve:      {result['curve']}\nepisode:    {result['gif']}\n"
          f"checkpoint: {result['checkpoint']}")
    return 0
