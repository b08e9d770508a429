"""PPO from distilled students: does reinforcement learning improve a DAgger student? Over seeds.

    python benchmarks/rl/bench_finetune.py --task laptop --seeds 0 1 --frames 100000 \
        --students 'runs/distill_laptop_dagger_novel_s{seed}' --json benchmarks/results/rl/finetune_laptop.json

Seed ``s`` fine-tunes the student in ``--students`` (``{seed}`` filled in) with ``dexart-lite train
--preset finetune --init-from <student>/checkpoint.pt --seed s`` into
``runs/finetune_<task>[_<variant>]_s<seed>``; ``--set FIELD=VALUE`` changes PPOConfig fields (with
``--variant``, e.g. ``--variant nowarmup --set critic_warmup=0`` for the run without the critic
warm-up). A finished seed is read back, an interrupted one resumes from its checkpoint (``study.run_arm``,
the rule every multi-seed script shares). Seeds run one after the other, alone.

The student's success is its own evaluation (``eval_<split>.json`` of the distillation run, same
evaluation seed and episodes per object; re-evaluated if those differ): it is the curve's frame 0.
Writes ``student_seen``, ``student_unseen``, ``seen_success``, ``unseen_success`` (means over seeds),
``per_seed`` (with the per-batch log: success and stage fractions of the collected, stochastic
episodes, the losses, ``critic_warmup``), ``frames``, ``wall_time_s`` (per seed, PPO and its final
evaluation), ``command``, ``machine``; and a PNG next to the JSON.

``--heldout-episodes N --heldout-seed S`` adds a second, larger evaluation of every seed's student and
final policy, on an evaluation seed that took no part in choosing settings (the per-run evaluation
above, 3 episodes per object, cannot separate a 0.1 change on 6 unseen objects). Its results are
cached next to each checkpoint (``heldout_<split>_e<N>_seed<S>.json``) and run ``--jobs`` at a time
(success does not depend on timing, so these may run side by side).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl import ppo
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint
from dexart_lite.rl.evaluate import evaluate, evaluate_many
from dexart_lite.study import run_arm
from dexart_lite.utils import (benchmark_results, fast_mode, parse_overrides, provenance, save_figure, sibling_script,
                               write_json)

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")
SPLITS = ("seen", "unseen")
KEEP = ("frames", "batch", "success_rate", "episode_return", "stage2_frac", "stage3_frac", "progress",
        "loss_objective", "loss_critic", "explained_variance", "kl_approx", "clip_fraction", "log_std",
        "critic_warmup", "bc_weight", "kl_init", "update_steps_frac", "loss_sil", "sil_positive", "wall_s")


def student_success(student: Path, cfg: ppo.PPOConfig) -> dict:
    """The student's deterministic success per split: its distillation evaluation when that used the
    same evaluation seed, episodes and cloud size as ``cfg``; else evaluated now."""
    payload = load_checkpoint(student / "checkpoint.pt")
    own = payload["config"]
    same = (own.get("eval_seed"), own.get("eval_episodes"), own.get("num_points"), own.get("max_episode_steps")) == \
        (cfg.eval_seed, cfg.eval_episodes, cfg.num_points, cfg.max_episode_steps)
    out = {}
    for split in SPLITS:
        file = student / f"eval_{split}.json"
        if same and file.exists():
            out[split] = json.loads(file.read_text())["success_rate"]
        else:
            net = actor_critic_from_checkpoint(payload, student / "checkpoint.pt")
            out[split] = evaluate(net, cfg.task, split, cfg.eval_episodes, cfg.eval_seed, cfg.env_kwargs())["success_rate"]
    return out


def run_seed(seed: int, student: str, cfg: ppo.PPOConfig) -> dict:
    """One seed through ``study.run_arm``: trained, continued from its checkpoint, or read back when its folder
    holds a finished run with the same settings; with the student's success."""
    record = run_arm(cfg)
    if record["resumed"]:
        print(f"{cfg.out}: finished before, read back")
    before = student_success(Path(student), cfg)
    print(f"seed {seed}: student {before['seen']:.2f} / {before['unseen']:.2f} -> PPO {record['seen_success']:.2f} / "
          f"{record['unseen_success']:.2f} (seen / unseen), {record['wall_time_s'] / 60:.1f} min")
    return {"seed": seed, "student": student, "student_seen": before["seen"], "student_unseen": before["unseen"],
            "seen_success": record["seen_success"], "unseen_success": record["unseen_success"],
            "frames": record["frames"], "wall_time_s": record["wall_time_s"], "resumed": record["continued"],
            "history": [{k: row[k] for k in KEEP if k in row} for row in record["history"]],
            "config": record["config"]}


def heldout(per_seed: list[dict], episodes: int, seed: int, jobs: int) -> dict:
    """Student and final policy of every seed evaluated with ``episodes`` per object on both splits at
    env seed ``seed``; each evaluation cached as JSON next to its checkpoint."""
    checkpoint = lambda folder: str(Path(folder) / ppo.CHECKPOINT)  # noqa: E731
    folders = [f for r in per_seed for f in (r["student"], r["config"]["out"])]
    results = evaluate_many([(checkpoint(f), s) for f in folders for s in SPLITS], episodes, seed, jobs)

    def rates(folder: str) -> dict:
        out = {}
        for split in SPLITS:
            res = results[(checkpoint(folder), split)]
            out[split] = {"success": res["success_rate"], "episodes": res["episodes"],
                          "objects": {name: o["success_rate"] for name, o in res["objects"].items()}}
        return out

    rows = []
    for r in per_seed:
        before, after = rates(r["student"]), rates(r["config"]["out"])
        rows.append({"seed": r["seed"], "student_seen": before["seen"]["success"],
                     "student_unseen": before["unseen"]["success"], "seen_success": after["seen"]["success"],
                     "unseen_success": after["unseen"]["success"],
                     "episodes": {split: after[split]["episodes"] for split in SPLITS},
                     "objects": {"student": {s: before[s]["objects"] for s in SPLITS},
                                 "final": {s: after[s]["objects"] for s in SPLITS}}})
    keys = ("student_seen", "student_unseen", "seen_success", "unseen_success")
    return {"episodes_per_object": episodes, "seed": seed,
            **{k: float(np.mean([row[k] for row in rows])) for k in keys}, "per_seed": rows}


@dataclass
class Flags:
    """This script's own flags (and --set: PPOConfig fields); the shared ones come from the harness."""

    students: str = field(default="", metadata={"help": "student run folder per seed, with {seed}"})
    variant: str = field(default="", metadata={"help": "a name for --set, in the run folders"})
    heldout_episodes: int = field(default=0, metadata={"min": 0, "help": "also evaluate students and final policies "
                                  "with this many episodes per object"})
    heldout_seed: int = field(default=1000, metadata={"help": "env seed of the held-out evaluation"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", seeds=[0, 1])
    add_config_arguments(parser, Flags, overrides=False, required=("students",))
    harness.options(parser, "runs", frames=300_000, helps={"frames": "PPO frames per seed"})
    # by hand: these FIELD=VALUE pairs change the finetune preset, not the PPOConfig defaults add_config_arguments reads
    parser.add_argument("--set", dest="overrides", nargs="+", default=[], metavar="FIELD=VALUE",
                        help="PPOConfig fields to change from the finetune preset, e.g. critic_warmup=0")
    harness.options(parser, json=None, helps={"json": "default benchmarks/results/rl/finetune_<task>.json"})
    harness.options(parser, "jobs", helps={"jobs": "held-out evaluations run side by side (training: one seed at "
                                                   "a time)"})
    args = parser.parse_args(argv)
    requested = parse_overrides(args.overrides, ppo.PPOConfig)
    if requested and not args.variant:
        raise ValueError("--set needs a --variant name (its runs must not mix with the defaults' folders)")
    path = args.json or RESULTS / f"finetune_{args.task}.json"
    overrides = dict(requested)
    if fast_mode():  # a smoke run of the script itself, not evidence
        overrides.update(num_points=32, max_episode_steps=10, frames_per_batch=100, minibatch=50, epochs=1,
                         workers=0, eval_episodes=1, critic_warmup=1, progress=False)
        if args.json is None:
            path = args.runs / "bench_finetune_fast.json"

    def job(seed: int) -> dict:
        name = "_".join(filter(None, ("finetune", args.task, args.variant, f"s{seed}")))
        student = args.students.format(seed=seed)
        return {"seed": seed, "student": student, "cfg": ppo.preset(
            "finetune", task=args.task, frames=args.frames, seed=seed, out=str(args.runs / name),
            init_from=str(Path(student) / "checkpoint.pt"), **overrides)}

    per_seed = list(harness.each(run_seed, [job(seed) for seed in args.seeds], desc="seeds"))
    mean = lambda key: float(np.mean([r[key] for r in per_seed]))  # noqa: E731
    std = lambda key: float(np.std([r[key] for r in per_seed]))  # noqa: E731
    result = {"task": args.task, "seeds": args.seeds, "preset": "finetune", "variant": args.variant,
              "overrides": requested, "frames": args.frames,
              **{k: mean(k) for k in ("student_seen", "student_unseen", "seen_success", "unseen_success")},
              **{f"{k}_std": std(k) for k in ("seen_success", "unseen_success")},
              "wall_time_s": [round(r["wall_time_s"], 1) for r in per_seed],
              "eval_episodes_per_object": per_seed[0]["config"]["eval_episodes"], "per_seed": per_seed,
              **provenance(__file__, argv),
              "note": "PPO (reinforcement learning) started from DAgger students; frame 0 is the student"}
    if args.heldout_episodes:
        result["heldout"] = heldout(per_seed, args.heldout_episodes, args.heldout_seed, args.jobs)
        h = result["heldout"]
        print(f"held-out ({args.heldout_episodes} episodes per object, seed {args.heldout_seed}): students "
              f"{h['student_seen']:.2f} / {h['student_unseen']:.2f} -> PPO {h['seen_success']:.2f} / "
              f"{h['unseen_success']:.2f}")
    write_json(path, result)
    plot(per_seed, path.with_suffix(".png"), f"PPO from DAgger students, {args.task}"
         + (f" ({args.variant})" if args.variant else ""), result.get("heldout"))
    print(f"{args.task}: students {result['student_seen']:.2f} / {result['student_unseen']:.2f} -> PPO "
          f"{result['seen_success']:.2f} / {result['unseen_success']:.2f}; wrote {path}")
    return result


def plot(per_seed: list[dict], path: Path, title: str, held: dict | None = None) -> None:
    """Deterministic success at frame 0 (the student) and at the end (seen: solid, unseen: dashed), the
    success of the collected, stochastic episodes of every batch (thin) and, if given, the held-out
    evaluation's means over seeds (black)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for r in per_seed:
        end = r["frames"]
        line, = ax.plot([0, end], [r["student_seen"], r["seen_success"]], marker="o", label=f"seed {r['seed']}: seen")
        ax.plot([0, end], [r["student_unseen"], r["unseen_success"]], marker="s", ls="--", color=line.get_color(),
                label=f"seed {r['seed']}: unseen")
        rows = [h for h in r["history"] if h.get("success_rate") == h.get("success_rate")]  # skip NaN
        ax.plot([h["frames"] for h in rows], [h["success_rate"] for h in rows], lw=0.8, alpha=0.5,
                color=line.get_color(), label=f"seed {r['seed']}: collected episodes (std {np.exp(r['history'][0]['log_std']):.2f})")
    if held:
        end = per_seed[0]["frames"]
        for split, ls, marker in (("seen", "-", "o"), ("unseen", "--", "s")):
            ax.plot([0, end], [held[f"student_{split}"], held[f"{split}_success"]], color="black", lw=2, ls=ls,
                    marker=marker, label=f"held-out, mean of seeds ({held['episodes_per_object']} per object): {split}")
    ax.set(xlabel="PPO frames", ylabel="success rate", ylim=(-0.05, 1.05), title=title)
    ax.legend(fontsize=7)
    save_figure(fig, path, dpi=120)


if __name__ == "__main__":
    main()
