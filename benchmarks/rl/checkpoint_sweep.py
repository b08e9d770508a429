"""Held-out success of several checkpoints of the same runs: how far a policy moves from checkpoint to checkpoint.

    python benchmarks/rl/checkpoint_sweep.py --jobs 2 --json benchmarks/results/rl/toilet_reverse_checkpoint_sweep.json \\
        --start s0=runs/curriculum/toilet_cloud_student_s0/checkpoint.pt \\
        s0=2855ce6:benchmarks/results/rl/curriculum/checkpoints/toilet_cloud_student_anchored_floor_reverse_d17_s0/checkpoint.pt \\
        s0=runs/curriculum/toilet_cloud_student_anchored_floor_reverse_d17_s0/checkpoint.pt

Why: one RL run's last checkpoint is one draw. On toilets two checkpoints 176k frames apart differed by 0.14 on the
seen objects (seed 0 of the reverse curriculum, 0.51 -> 0.37), as much as RL gained over the student, so a run is
judged better by the mean over its later checkpoints than by the last alone.

Each positional argument is ``SERIES=CHECKPOINT``: a series label (a seed, say) and a checkpoint file, or
``REV:path`` for one in git history (a run's committed checkpoint at an earlier commit; extracted under ``--cache``
with the held-out evaluations committed beside it that measured it, which are read back instead of run again).
``--start`` names the checkpoint a series started from (its student), drawn at 0 RL frames; the others sit at their
checkpoint's frames.
Every checkpoint is evaluated as ``paired_eval.py`` does: deterministic actions from the true reset, ``--eval-episodes``
per seen and unseen object at env seed ``--seed`` (1000, held out), cached next to the checkpoint
(``rl.evaluate.evaluate_many``), so each checkpoint needs a folder of its own.

Written to ``--json``: episodes_per_object, eval_seed, series (label -> start and checkpoints, each: checkpoint,
frames, and per split success, its object-stratified se and success per object), summary (per series and split:
the start, the mean, min, max and swing (max - min) of the RL checkpoints of at least ``--summary-from`` frames
(``from_frames``), and the mean's gain over the start with its se; the mean gain over the series), command, machine;
and a plot beside it (success against RL frames).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.checkpoint import load_checkpoint
from dexart_lite.rl.evaluate import evaluate_many, split_stats
from dexart_lite.utils import provenance, save_figure, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

SPLITS = ("seen", "unseen")
REPO = Path(__file__).resolve().parents[2]  # git paths are relative to the repository root


def parse_spec(text: str) -> tuple[str, str]:
    """``SERIES=CHECKPOINT`` -> (series, checkpoint spec)."""
    label, sep, spec = text.partition("=")
    if not sep or not label or not spec:
        raise argparse.ArgumentTypeError(f"expected SERIES=CHECKPOINT (a file or REV:path in git), got {text!r}")
    return label, spec


def resolve(spec: str, cache: Path) -> Path:
    """The checkpoint file of ``spec``: the file itself, or ``REV:path`` extracted from git to ``cache/REV/path``
    together with the ``heldout_*.json`` evaluations committed beside it at that revision that measured it (their
    ``frames`` are the checkpoint's; written after the checkpoint, so that ``evaluate_many`` reads them back as newer
    than it). An evaluation of another checkpoint of the run, committed beside this one before it was evaluated
    again, is left out, and this checkpoint is evaluated anew."""
    if Path(spec).is_file():
        return Path(spec)
    rev, sep, path = spec.partition(":")
    if not sep:
        raise FileNotFoundError(f"checkpoint not found: {spec} (a file, or REV:path for one in git history)")
    target = cache / rev / path
    if not target.is_file():
        def show(name: str) -> bytes:
            done = subprocess.run(["git", "show", f"{rev}:{name}"], capture_output=True, cwd=REPO)
            if done.returncode:
                raise FileNotFoundError(f"{rev}:{name} is not in git: {done.stderr.decode().strip()}")
            return done.stdout

        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(show(path))
        folder = str(Path(path).parent)
        names = subprocess.run(["git", "ls-tree", "--name-only", f"{rev}:{folder}"], capture_output=True,
                               text=True, cwd=REPO).stdout.split()
        frames = checkpoint_frames(target)
        for name in (n for n in names if n.startswith("heldout_") and n.endswith(".json")):
            text = show(f"{folder}/{name}")
            measured = json.loads(text).get("frames")
            if measured == frames:
                (target.parent / name).write_bytes(text)
            else:  # committed beside this checkpoint but measured on another one (re-evaluated in a later commit)
                print(f"{rev}:{folder}/{name} evaluated a checkpoint at {measured} frames, this one has {frames}: "
                      "evaluated again")
    return target


def checkpoint_frames(path: Path) -> int:
    """The training frames a checkpoint file records."""
    return load_checkpoint(path)["frames"]


def summarise(series: dict, from_frames: int = 0) -> dict:
    """Per series and split, over its RL checkpoints of at least ``from_frames``: start, their mean / min / max /
    swing, the mean's gain over the start and its se (episodes are independent, so the se of a mean over n
    checkpoints is sqrt(sum se^2) / n); and per split the gain averaged over the series that have a start."""
    out = {"from_frames": from_frames, "series": {}}
    for label, s in series.items():
        entry, kept = {}, [c for c in s["checkpoints"] if c["frames"] >= from_frames]
        if not kept:
            raise ValueError(f"series {label} has no checkpoint of at least {from_frames} frames (--summary-from)")
        for split in SPLITS:
            values = [c[split]["success"] for c in kept]
            mean = float(np.mean(values))
            se = math.sqrt(sum(c[split]["se"] ** 2 for c in kept)) / len(values)
            entry[split] = {"mean": mean, "mean_se": se, "min": min(values), "max": max(values),
                            "swing": max(values) - min(values)}
            if s["start"] is not None:
                start = s["start"][split]
                entry[split].update(start=start["success"], gain=mean - start["success"],
                                    gain_se=math.hypot(se, start["se"]))
        out["series"][label] = entry
    with_start = [e for label, e in out["series"].items() if series[label]["start"] is not None]
    for split in SPLITS:
        if with_start:
            out[f"{split}_gain"] = float(np.mean([e[split]["gain"] for e in with_start]))
            out[f"{split}_gain_se"] = math.sqrt(sum(e[split]["gain_se"] ** 2 for e in with_start)) / len(with_start)
    return out


def plot(series: dict, path: Path) -> Path:
    """Success against RL frames, per series: seen solid, unseen dashed, the start at 0."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for i, (label, s) in enumerate(series.items()):
        points = ([s["start"]] if s["start"] is not None else []) + s["checkpoints"]
        for split, style in zip(SPLITS, ("-", "--")):
            ax.errorbar([p["frames"] for p in points], [p[split]["success"] for p in points],
                        yerr=[p[split]["se"] for p in points], fmt="o" + style, color=f"C{i}", capsize=2, ms=4,
                        label=f"{label} {split}")
    ax.set_xlabel("RL frames (0: the start)")
    ax.set_ylabel("held-out success")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7, ncol=2)
    return save_figure(fig, path)


@dataclass
class Flags:
    """This script's own arguments; the shared ones come from the harness."""

    checkpoints: list[tuple] = field(default_factory=list, metadata={
        "positional": True, "parse": parse_spec, "help": "SERIES=CHECKPOINT (a file or REV:path)"})
    start: list[tuple] = field(default_factory=list, metadata={
        "parse": parse_spec, "help": "SERIES=CHECKPOINT a series started from (drawn at 0 RL frames)"})
    summary_from: int = field(default=0, metadata={"min": 0, "help": "summarise the checkpoints of at least this many "
                              "RL frames (the earlier ones are still evaluated and drawn)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, eval_episodes=10)
    harness.options(parser, "jobs", seed=1000, helps={"seed": "env seed of every evaluation (1000: held out)"})
    harness.options(parser, "json", cache=Path("runs/checkpoint_sweep"), required=("json",))
    args = parser.parse_args(argv)
    starts = dict(args.start)
    unknown = sorted(set(starts) - {label for label, _ in args.checkpoints})
    if unknown:
        raise ValueError(f"--start for series without checkpoints: {', '.join(unknown)}")
    files = {spec: resolve(spec, args.cache) for spec in [*starts.values(), *(c for _, c in args.checkpoints)]}
    results = evaluate_many([(str(f), s) for f in files.values() for s in SPLITS], args.eval_episodes, args.seed,
                            args.jobs)

    def point(spec: str, frames: int | None = None) -> dict:  # frames: the checkpoint's own, kept in its evaluation
        evaluated = {s: results[(str(files[spec]), s)] for s in SPLITS}
        return {"checkpoint": spec, "frames": evaluated["seen"]["frames"] if frames is None else frames,
                **{s: split_stats(r) for s, r in evaluated.items()}}

    series = {}
    for label, spec in args.checkpoints:
        s = series.setdefault(label, {"start": point(starts[label], 0) if label in starts else None, "checkpoints": []})
        s["checkpoints"].append(point(spec))
    for s in series.values():
        s["checkpoints"].sort(key=lambda c: c["frames"])
    out = {"episodes_per_object": args.eval_episodes, "eval_seed": args.seed, "series": series,
           "summary": summarise(series, args.summary_from), **provenance(__file__, argv), "jobs": args.jobs}
    write_json(args.json, out)
    plot(series, args.json.with_suffix(".png"))
    for label, s in series.items():
        print(f"{label}: " + "; ".join(f"{c['frames']}: " + " / ".join(f"{c[x]['success']:.2f}" for x in SPLITS)
                                       for c in s["checkpoints"]))
    e = out["summary"]
    for split in SPLITS:
        if f"{split}_gain" in e:
            print(f"{split}: mean over checkpoints minus start {e[f'{split}_gain']:+.2f} ± {e[f'{split}_gain_se']:.2f}")
    print(f"wrote {args.json}")
    return out


if __name__ == "__main__":
    main()
