"""Does PPO fine-tuning move a distilled student? Every committed fine-tune run of a task, pooled.

``bench_finetune.py`` writes one JSON per variant (``finetune_<task>*.json``); each seed's ``heldout``
row evaluates the student and the fine-tuned policy on the same held-out episodes (20 per object,
env seed 1000), so each row is a paired before/after. One variant's 2 seeds cannot tell a small
effect from the spread between seeds; pooled over all variants they say how large a change 300k PPO
frames make at all. This script reads those rows (no training), and reports per run the change on
seen and unseen objects, and per split the mean and standard deviation of the change over the runs
and how many runs went up, stayed equal or went down.

    python benchmarks/rl/finetune_summary.py --task faucet --json benchmarks/results/rl/finetune_faucet_summary.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

from dexart_lite.utils import benchmark_results, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")
SPLITS = ("seen", "unseen")


def runs(task: str, results: Path = RESULTS) -> list[dict]:
    """One row per seed of every ``finetune_<task>*.json`` with held-out evaluations: the variant, its
    overrides, the student, and the held-out success before and after."""
    rows = []
    for path in sorted(results.glob(f"finetune_{task}*.json")):
        result = json.loads(path.read_text())
        if "heldout" not in result or result.get("fast_mode"):
            continue
        students = {r["seed"]: r.get("student") for r in result["per_seed"]}
        for r in result["heldout"]["per_seed"]:
            rows.append({"file": path.name, "variant": result.get("variant") or "finetune",
                         "overrides": result.get("overrides", {}), "seed": r["seed"],
                         "student": students.get(r["seed"]),
                         "frames": result["frames"], "episodes_per_object": result["heldout"]["episodes_per_object"],
                         **{f"{w}_{s}": r[k] for s in SPLITS
                            for w, k in (("before", f"student_{s}"), ("after", f"{s}_success"))}})
    return rows


def pooled(rows: list[dict]) -> dict:
    """Per split: the change after - before, its mean and standard deviation over the runs (population
    std for one run), and the runs that went up, stayed equal and went down."""
    out = {}
    for s in SPLITS:
        deltas = [r[f"after_{s}"] - r[f"before_{s}"] for r in rows]
        out[s] = {"mean_change": statistics.fmean(deltas), "std_change": statistics.pstdev(deltas) if len(deltas) < 2
                  else statistics.stdev(deltas), "up": sum(d > 1e-9 for d in deltas),
                  "equal": sum(abs(d) <= 1e-9 for d in deltas), "down": sum(d < -1e-9 for d in deltas),
                  "runs": len(deltas)}
    return out


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, task="faucet")
    harness.options(parser, results=RESULTS, helps={"results": "folder of the finetune_<task>*.json files"})
    harness.options(parser, "json", helps={"json": "write the summary here"})
    args = parser.parse_args(argv)
    rows = runs(args.task, args.results)
    if not rows:
        raise SystemExit(f"no finetune_{args.task}*.json with held-out evaluations in {args.results}")
    summary = pooled(rows)
    print("| file | variant | seed | held-out seen: student -> PPO | unseen: student -> PPO |\n|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['file']} | {r['variant']} | {r['seed']} | {r['before_seen']:.2f} -> {r['after_seen']:.2f} | "
              f"{r['before_unseen']:.2f} -> {r['after_unseen']:.2f} |")
    for s, p in summary.items():
        print(f"{s}: change {p['mean_change']:+.3f} +- {p['std_change']:.3f} over {p['runs']} runs "
              f"({p['up']} up, {p['equal']} equal, {p['down']} down)")
    result = {"task": args.task, "runs": rows, "pooled": summary,
              "note": "paired held-out evaluations read from the committed bench_finetune.py JSONs; no training",
              **provenance(__file__, argv)}
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return result


if __name__ == "__main__":
    main()
