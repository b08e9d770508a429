"""Stop on a validation criterion: per run, the checkpoint that succeeds most on the seen objects at a validation
env seed, then its held-out success on both splits beside the run's last checkpoint and its start.

    python benchmarks/rl/select_checkpoint.py --jobs 2 --json benchmarks/results/rl/laptop_floor_b16k_selected.json \\
        --start s0=runs/curriculum/laptop_cloud_student_s0/checkpoint.pt \\
        s1=runs/curriculum/laptop_cloud_student_s1/checkpoint.pt -- \\
        s0=b3693a9:benchmarks/results/rl/curriculum/checkpoints/laptop_cloud_student_anchored_floor_flat_b16k_s0/checkpoint.pt \\
        s0=runs/snapshots/floor5_s0_1796300000/checkpoint.pt ...

Why: the checkpoints of one PPO run swing from one to the next by about as much as RL gains over its student
(``checkpoint_sweep.py``: on laptops seed 0's seen success went 0.72, 0.83, 0.74, 0.73, 0.77 over five checkpoints
~80k frames apart, se ~0.04 each), so the last checkpoint is one draw among them. Choosing the best one is the usual
answer (an evaluation callback that keeps the best model), and it is only honest if the choice is made on data the
reported figure does not use.

The protocol, in order:

1. The candidates are fixed before any is evaluated: every checkpoint named on the command line (a run's
   snapshots, or ``REV:path`` for one committed in git history, as in ``checkpoint_sweep.py``).
2. Each candidate is evaluated on the **seen** (training) objects only, ``--select-episodes`` per object at env
   seed ``--select-seed`` (100, the seed of the runs' own evaluation), deterministic actions from the true reset.
3. Per series (a seed's run) the candidate with the highest validation success is picked; a tie goes to the one
   trained longer.
4. Only the pick, the series' last candidate (the plain "stop at the end" rule) and its start are evaluated as
   ``paired_eval.py`` does: ``--eval-episodes`` per seen and unseen object at env seed ``--seed`` (1000, held out).

Unseen objects play no part in the choice, and the held-out seen episodes start from other initial states (another
seed of the env's RNG) than the ones chosen on, so the pick's held-out figures are what a user who stops this way
would measure. Evaluations are cached beside each checkpoint (``rl.evaluate.evaluate_many``), so each checkpoint
needs a folder of its own.

Written to ``--json``: the protocol's settings, series (label -> start, candidates with their frames and validation
success, picked and last with their held-out success per split and its object-stratified se), summary (per split:
the mean over series of start / picked / last and the gains picked - start, last - start and picked - last with
their se's), command, machine; and a plot beside it (validation success against RL frames, the pick marked, and the
held-out points).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.evaluate import check_phase_seed, evaluate_many, split_stats
from dexart_lite.utils import provenance, save_figure, sibling_script, write_json

harness = sibling_script(__file__, "_harness")
sweep = sibling_script(__file__, "checkpoint_sweep")  # its SERIES=CHECKPOINT parsing and git checkouts

SPLITS = ("seen", "unseen")


def pick(candidates: list[dict]) -> dict:
    """The candidate with the highest validation success; a tie goes to the one with more frames."""
    if not candidates:
        raise ValueError("no candidate checkpoints to choose from")
    return max(candidates, key=lambda c: (c["validation"]["success"], c["frames"]))


def summarise(series: dict) -> dict:
    """Per split, the mean over series of the start, the pick and the last checkpoint, and the gains between them.
    Series are independent runs and episodes independent draws, so the se of a mean over n series is
    sqrt(sum se^2) / n, and the se of a difference adds the two in quadrature (an upper bound where the pick is the
    last checkpoint: the same episodes then, a difference of exactly 0)."""
    out = {}
    n = len(series)
    for split in SPLITS:
        def mean(which: str) -> tuple[float, float]:
            values = [s[which][split] for s in series.values()]
            return (float(np.mean([v["success"] for v in values])),
                    math.sqrt(sum(v["se"] ** 2 for v in values)) / n)

        entry = {}
        for which in ("start", "picked", "last"):
            entry[which], entry[f"{which}_se"] = mean(which)
        for a, b in (("picked", "start"), ("last", "start"), ("picked", "last")):
            entry[f"{a}_minus_{b}"] = entry[a] - entry[b]
            entry[f"{a}_minus_{b}_se"] = math.hypot(entry[f"{a}_se"], entry[f"{b}_se"])
        out[split] = entry
    return out


def plot(series: dict, path: Path) -> Path:
    """Validation success (seen objects, validation seed) against RL frames per series, the pick circled; the
    held-out seen success of the pick and of the last checkpoint as crosses."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for i, (label, s) in enumerate(series.items()):
        frames = [c["frames"] for c in s["candidates"]]
        ax.plot(frames, [c["validation"]["success"] for c in s["candidates"]], "o-", color=f"C{i}", ms=4,
                label=f"{label} validation (seen)")
        ax.plot(s["picked"]["frames"], s["picked"]["validation"]["success"], "o", ms=11, mfc="none", color=f"C{i}")
        for which, marker in (("picked", "x"), ("last", "+")):
            ax.plot(s[which]["frames"], s[which]["seen"]["success"], marker, ms=9, color=f"C{i}",
                    label=f"{label} {which}, held-out seen")
    ax.set_xlabel("RL frames")
    ax.set_ylabel("success")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7, ncol=2)
    return save_figure(fig, path)


@dataclass
class Flags:
    """This script's own arguments; the shared ones come from the harness."""

    checkpoints: list[tuple] = field(default_factory=list, metadata={
        "positional": True, "parse": sweep.parse_spec, "help": "SERIES=CHECKPOINT candidates (a file or REV:path)"})
    start: list[tuple] = field(default_factory=list, metadata={
        "parse": sweep.parse_spec, "help": "SERIES=CHECKPOINT each series started from (its student)"})
    select_episodes: int = field(default=5, metadata={"help": "validation episodes per seen object"})
    select_seed: int = field(default=100, metadata={"help": "env seed of the validation episodes (one of "
                                                            "rl.evaluate.VALIDATION_SEEDS)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, required=("start",))
    harness.options(parser, eval_episodes=10, helps={"eval_episodes": "held-out episodes per seen and unseen object"})
    harness.options(parser, "jobs", seed=1000, helps={"seed": "env seed of the held-out evaluation"})
    harness.options(parser, "json", cache=Path("runs/checkpoint_sweep"), required=("json",))
    args = parser.parse_args(argv)
    if args.select_episodes < 1:
        raise ValueError(f"--select-episodes must be >= 1, got {args.select_episodes}")
    if args.select_seed == args.seed:
        raise ValueError(f"--select-seed must differ from the held-out --seed ({args.seed}): the choice must not "
                         "see the episodes it is reported on")
    check_phase_seed("validation", args.select_seed)  # a test seed never chooses
    starts = dict(args.start)
    labels = list(dict.fromkeys(label for label, _ in args.checkpoints))
    if sorted(starts) != sorted(labels):
        raise ValueError(f"every series needs one --start and candidates: series {', '.join(labels)}, "
                         f"starts {', '.join(starts)}")
    files = {spec: sweep.resolve(spec, args.cache) for spec in [*starts.values(), *(c for _, c in args.checkpoints)]}

    validation = evaluate_many([(str(files[c]), "seen") for _, c in args.checkpoints], args.select_episodes,
                               args.select_seed, args.jobs)
    series = {}
    for label, spec in args.checkpoints:
        result = validation[(str(files[spec]), "seen")]
        series.setdefault(label, {"start": {"checkpoint": starts[label], "frames": 0}, "candidates": []})
        series[label]["candidates"].append({"checkpoint": spec, "frames": result["frames"],
                                            "validation": split_stats(result)})
    for s in series.values():
        s["candidates"].sort(key=lambda c: c["frames"])
        s["picked"], s["last"] = dict(pick(s["candidates"])), dict(s["candidates"][-1])

    held = [s[which]["checkpoint"] for s in series.values() for which in ("start", "picked", "last")]
    heldout = evaluate_many([(str(files[c]), split) for c in held for split in SPLITS], args.eval_episodes, args.seed,
                            args.jobs)
    for s in series.values():
        for which in ("start", "picked", "last"):
            s[which].update({split: split_stats(heldout[(str(files[s[which]["checkpoint"]]), split)])
                             for split in SPLITS})
    out = {"protocol": {"select_split": "seen", "select_episodes_per_object": args.select_episodes,
                        "select_seed": args.select_seed, "episodes_per_object": args.eval_episodes,
                        "eval_seed": args.seed},
           "series": series, "summary": summarise(series), **provenance(__file__, argv), "jobs": args.jobs}
    write_json(args.json, out)
    plot(series, args.json.with_suffix(".png"))
    for label, s in series.items():
        print(f"{label}: validation " + ", ".join(f"{c['frames']}: {c['validation']['success']:.2f}"
                                                  for c in s["candidates"]))
        for which in ("start", "picked", "last"):
            print(f"  {which} ({s[which]['frames']} frames): held out "
                  + " / ".join(f"{s[which][x]['success']:.2f}" for x in SPLITS))
    for split, e in out["summary"].items():
        print(f"{split}: picked {e['picked']:.2f}, last {e['last']:.2f}, start {e['start']:.2f}; picked - start "
              f"{e['picked_minus_start']:+.2f} ± {e['picked_minus_start_se']:.2f}, picked - last "
              f"{e['picked_minus_last']:+.2f} ± {e['picked_minus_last_se']:.2f}")
    print(f"wrote {args.json}")
    return out


if __name__ == "__main__":
    main()
