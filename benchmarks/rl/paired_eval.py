"""Each point-cloud RL run against the student it started from, evaluated again side by side with more episodes.

    python benchmarks/rl/paired_eval.py --jobs 2                    # every RL run set with a student, 10 eps/object
    python benchmarks/rl/paired_eval.py --run-sets laptop_cloud_student_anchored --eval-episodes 20

Why: the runs' own evaluations (``curriculum_runs.py``) use 3 episodes per object, a standard error of 0.07-0.11 per
seed and split, as large as any change RL made. Here, for every committed RL run set that starts from a distilled
student (``benchmarks/results/rl/curriculum/<task>_cloud_<recipe>.json`` with a ``student`` entry) and each of its
seeds, the RL policy (``runs/curriculum/<task>_cloud_<recipe>_s<seed>/checkpoint.pt``) and the student it started
from (the checkpoint its config's ``init_from`` names) are evaluated as ``dexart-lite eval`` does: deterministic
actions from the true reset, ``--eval-episodes`` per seen and unseen object, both at env seed 1000, a held-out seed (the
runs' own evaluations, which chose recipes and zoo entries, use 100). Each evaluation is cached next to its checkpoint
(``heldout_<split>_e<N>_seed<S>.json``, through ``rl.evaluate.evaluate_many``, as ``bench_finetune.py
--heldout-episodes`` does) and read back by a later call. The checkpoints are not in git (``runs/`` is untracked):
the script needs the runs on this machine and names any that are missing.

Standard errors are stratified by object, since every object gets the same k episodes:
se = sqrt(sum_o p_o (1 - p_o) / k) / n_objects; a difference's se adds the two in quadrature (independent episodes);
a run set's mean delta over its seeds has se = sqrt(sum of the seeds' se^2) / n_seeds.

Written to ``benchmarks/results/rl/paired_eval.json``: episodes_per_object, eval_seed, runs (per run set and seed:
task, recipe, seed, rl_frames, student and rl, each per split {success, se, objects: success per object}; delta per
split {value, se}; the command and machine that measured it), summary (per run set: task, recipe, seeds, rl_frames,
and per split the mean student, rl and delta over the seeds with the delta's se), command, machine (of the latest
call); and ``paired_eval.png`` (the deltas). ``--run-sets`` re-evaluates the run sets named and keeps the other rows
of an existing ``--json`` as they were measured (same episodes and seed only), so one run set can be measured again
on a machine that has only its checkpoints.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.checkpoint import load_checkpoint
from dexart_lite.rl.evaluate import evaluate_many, split_stats
from dexart_lite.utils import benchmark_results, fast_mode, provenance, save_figure, sibling_script, write_json

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")
CURRICULUM = RESULTS / "curriculum"
SPLITS = ("seen", "unseen")


def run_sets(names: list[str] | None, folder: Path = CURRICULUM) -> list[dict]:
    """The committed RL run sets that start from a student (their JSON has a ``recipe`` and a ``student``), all or
    those named (file stems, e.g. ``laptop_cloud_student_anchored``)."""
    found = {p.stem: json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))}
    found = {stem: d for stem, d in found.items() if d.get("recipe") and d.get("student")}
    unknown = sorted(set(names or ()) - set(found))
    if unknown:
        raise ValueError(f"unknown run set(s) {', '.join(unknown)}; valid: {', '.join(found)}")
    return [found[n] for n in (names or found)]


def checkpoints(run_set: dict, runs: Path) -> list[dict]:
    """Per seed of a run set: its RL checkpoint and the student checkpoint that run started from."""
    pairs = []
    for row in run_set["per_seed"]:
        rl = runs / f"{run_set['task']}_{run_set['obs']}_{run_set['recipe']}_s{row['seed']}" / "checkpoint.pt"
        if not rl.is_file():
            raise FileNotFoundError(f"RL checkpoint not found: {rl} (the runs are not in git; train them with "
                                    f"{run_set['command']})")
        payload = load_checkpoint(rl)
        student = Path(payload["config"]["init_from"])
        if not student.is_file():
            raise FileNotFoundError(f"student checkpoint not found: {student} (named by {rl})")
        pairs.append({"task": run_set["task"], "recipe": run_set["recipe"], "seed": row["seed"],
                      "rl_frames": payload["frames"], "rl": rl, "student": student})
    return pairs


def merge_rows(previous: dict, rows: list[dict], episodes: int, seed: int) -> list[dict]:
    """The rows of an earlier paired_eval JSON (``previous``) whose run sets (task, recipe) were not evaluated again,
    and ``rows``, sorted by task, recipe and seed. Earlier rows without their own ``command`` / ``machine`` get
    the earlier file's. An earlier file with other episodes or seed cannot be merged (its deltas would not be
    comparable)."""
    if (previous["episodes_per_object"], previous["eval_seed"]) != (episodes, seed):
        raise ValueError(f"the existing results use {previous['episodes_per_object']} episodes per object at seed "
                         f"{previous['eval_seed']}, not {episodes} at {seed}: pass --json elsewhere")
    kept = harness.rows_not_rerun(previous, rows, lambda r: (r["task"], r["recipe"]), rows_key="runs")
    return sorted(kept + rows, key=lambda r: (r["task"], r["recipe"], r["seed"]))  # the order of a full call


def compare(student: dict, rl: dict) -> dict:
    """Per split, RL minus student and its se (``student``, ``rl``: split -> ``split_stats``)."""
    return {s: {"value": rl[s]["success"] - student[s]["success"],
                "se": math.hypot(rl[s]["se"], student[s]["se"])} for s in student}


def summarise(rows: list[dict]) -> list[dict]:
    """Per run set (task, recipe): the seeds' mean student, RL and delta per split, and the delta's se."""
    sets = {}
    for row in rows:
        sets.setdefault((row["task"], row["recipe"]), []).append(row)
    summary = []
    for (task, recipe), seeds in sets.items():
        entry = {"task": task, "recipe": recipe, "seeds": [r["seed"] for r in seeds],
                 "rl_frames": [r["rl_frames"] for r in seeds]}
        for s in SPLITS:
            entry[s] = {"student": float(np.mean([r["student"][s]["success"] for r in seeds])),
                        "rl": float(np.mean([r["rl"][s]["success"] for r in seeds])),
                        "delta": float(np.mean([r["delta"][s]["value"] for r in seeds])),
                        "delta_se": math.sqrt(sum(r["delta"][s]["se"] ** 2 for r in seeds)) / len(seeds)}
        summary.append(entry)
    return summary


def plot(summary: list[dict], rows: list[dict], path: Path) -> Path:
    """RL minus student per run set and split: the seeds' mean with its se, and each seed as a dot."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(summary), 3.4))
    for j, split in enumerate(SPLITS):
        x = np.arange(len(summary)) + (j - 0.5) * 0.35
        ax.bar(x, [e[split]["delta"] for e in summary], 0.35, yerr=[e[split]["delta_se"] for e in summary],
               capsize=3, label=split, alpha=0.7)
        for xi, e in zip(x, summary):
            seeds = [r["delta"][split]["value"] for r in rows if (r["task"], r["recipe"]) == (e["task"], e["recipe"])]
            ax.plot([xi] * len(seeds), seeds, "k.", ms=4)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(np.arange(len(summary)), [f"{e['task']}\n{e['recipe']}" for e in summary], fontsize=7)
    ax.set_ylabel("success: RL - student")
    ax.legend(fontsize=8)
    return save_figure(fig, path)


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    run_sets: list[str] | None = field(default=None, metadata={"help": "JSON stems under benchmarks/results/rl/"
                                      "curriculum (None: every RL run set that starts from a student)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, eval_episodes=10)
    harness.options(parser, "jobs", seed=1000, runs=Path("runs/curriculum"),
                    helps={"seed": "env seed of every evaluation: 1000, the held-out seed of bench_finetune.py, not "
                                   "the 100 of the runs' own evaluations that chose settings"})
    harness.options(parser, json=RESULTS / "paired_eval.json", helps={"json": "write the results here (and a PNG "
                                                                          "beside it)"})
    args = parser.parse_args(argv)
    if fast_mode() and args.json == RESULTS / "paired_eval.json":  # never overwrite the evidence with a smoke run
        raise ValueError("fast mode writes smoke results: pass --json elsewhere")
    pairs = [p for run_set in run_sets(args.run_sets) for p in checkpoints(run_set, args.runs)]
    # a student that starts several run sets (one per recipe) is evaluated once; cached next to each checkpoint
    work = [(str(p[who]), split) for p in pairs for who in ("student", "rl") for split in SPLITS]
    results = evaluate_many(work, args.eval_episodes, args.seed, args.jobs)
    rows = []
    for p in pairs:
        stats = {who: {s: split_stats(results[(str(p[who]), s)]) for s in SPLITS} for who in ("student", "rl")}
        rows.append({"task": p["task"], "recipe": p["recipe"], "seed": p["seed"], "rl_frames": p["rl_frames"],
                     "rl_checkpoint": str(p["rl"]), "student_checkpoint": str(p["student"]), **stats,
                     "delta": compare(stats["student"], stats["rl"]),
                     "wall_time_s": round(sum(results[(str(p[w]), s)]["wall_time_s"]
                                              for w in ("student", "rl") for s in SPLITS), 1)})
    meta = provenance(__file__, argv)
    for row in rows:
        row.update(command=meta["command"], machine=meta["machine"])
    if args.run_sets and args.json.is_file():
        rows = merge_rows(json.loads(args.json.read_text()), rows, args.eval_episodes, args.seed)
    summary = summarise(rows)
    out = {"episodes_per_object": args.eval_episodes, "eval_seed": args.seed, "runs": rows, "summary": summary,
           **meta, "jobs": args.jobs}
    write_json(args.json, out)
    plot(summary, rows, args.json.with_suffix(".png"))
    for e in summary:
        print(f"{e['task']} {e['recipe']}: " + ", ".join(
            f"{s} {e[s]['student']:.2f} -> {e[s]['rl']:.2f} ({e[s]['delta']:+.2f} ± {e[s]['delta_se']:.2f})"
            for s in SPLITS))
    print(f"wrote {args.json}")
    return out


if __name__ == "__main__":
    main()
