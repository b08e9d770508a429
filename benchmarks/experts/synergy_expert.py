"""Can the synergy hand still do each task? The scripted experts with their hands projected on 3 synergies.

``hand="synergy"`` (``dexart_lite.robot.synergy_targets``; not DexArt's) replaces the 16 hand joint
targets of the action by 3 numbers: knuckles, curl (index, middle and ring together) and thumb, each
moving its joints on a straight line from open to closed. A policy can then only make the hand shapes
on those lines. This script measures what that costs: every expert runs as in ``dexart-lite solve``
(same episodes and seeds as the committed ``solve_<task>_<split>.json``), its twist unchanged and its
hand targets replaced by their least-squares projection on the synergies (``SynergyScriptedPolicy``).
An expert that still succeeds shows that the smaller action space holds a solution of the task.

    python benchmarks/experts/synergy_expert.py --json benchmarks/results/experts/synergy_expert.json

Writes one row per task and split: the projected expert's success and stage next to the committed
success of the full-hand expert (read from ``solve_<task>_<split>.json``). Rows of an existing ``--json`` for tasks
and splits not run in this call are kept (with the command and machine that measured them); it must have used the
same episodes and seed.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from dexart_lite.experts.solve import solve
from dexart_lite.objects import SPLITS, list_objects
from dexart_lite.registration import TASKS
from dexart_lite.utils import benchmark_results, fast_mode, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks", "splits", "episodes_per_object", "seed", "json",
                    helps={"episodes_per_object": "as the committed solve_*.json"})
    args = parser.parse_args(argv)
    if fast_mode():  # a smoke run of the script itself, not evidence
        args.episodes_per_object = 1

    rows = []
    for task in args.tasks:
        for split in args.splits:
            object_names = [list_objects(task, split)[0].name] if fast_mode() else None
            start = time.perf_counter()
            res = solve(task, split, args.episodes_per_object, args.seed, object_names=object_names,
                        progress=not fast_mode(), env_kwargs={"hand": "synergy"})
            committed = RESULTS / f"solve_{task}_{split}.json"
            full = json.loads(committed.read_text()) if committed.is_file() else None
            same = full is not None and (full["episodes_per_object"], full["seed"]) == (
                args.episodes_per_object, args.seed) and not fast_mode()
            rows.append({"task": task, "split": split, "synergy_success": res["success_rate"],
                         "synergy_mean_max_stage": res["mean_max_stage"],
                         "synergy_success_per_object": res["success_per_object"],
                         "full_hand_success": full["success_rate"] if same else None,
                         "wall_time_s": time.perf_counter() - start})

    print("| task | split | expert, 16 hand joints (solve_*.json) | expert projected on 3 synergies | mean max stage |")
    print("|---|---|---|---|---|")
    for r in rows:
        full = "n/a" if r["full_hand_success"] is None else f"{r['full_hand_success']:.2f}"
        print(f"| {r['task']} | {r['split']} | {full} | {r['synergy_success']:.2f} | "
              f"{r['synergy_mean_max_stage']:.2f} |")
    rows = sorted(kept_rows(args, rows) + rows, key=lambda r: (TASKS.index(r["task"]), SPLITS.index(r["split"])))
    result = {"episodes_per_object": args.episodes_per_object, "seed": args.seed, "rows": rows,
              **provenance(__file__, argv)}
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return result


def kept_rows(args, rows: list[dict]) -> list[dict]:
    """The rows of an existing ``--json`` for the tasks and splits not run in this call, so that one task can be
    measured again (``--tasks bucket``) without running the others; refused where that file used other episodes or
    another seed (its rows would not be comparable)."""
    if not args.json or not Path(args.json).is_file():
        return []
    previous = json.loads(Path(args.json).read_text())
    kept = harness.rows_not_rerun(previous, rows, lambda r: (r["task"], r["split"]))
    if kept and (previous["episodes_per_object"], previous["seed"]) != (args.episodes_per_object, args.seed):
        raise ValueError(f"{args.json} holds rows of {previous['episodes_per_object']} episodes per object at seed "
                         f"{previous['seed']}, not {args.episodes_per_object} at {args.seed}: run every task or pass "
                         f"--json elsewhere")
    return kept


if __name__ == "__main__":
    main()
