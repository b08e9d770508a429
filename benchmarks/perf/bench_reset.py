"""Reset cost per task, this checkout next to an earlier commit (the price of exact replay).

Since exact replay (see ``DexArtEnv.reset``) a reset removes the previous object and loads the new
one, and every ``REBUILD_EVERY`` resets (bucket: every reset) the simulation is built anew. This
script times ``env.reset(seed=i)`` over ``--resets`` resets cycling through the split's objects
(rebuilds included, amortised) and, with ``--ref``, the same in a ``git worktree`` of that commit, the
two measured alternately in subprocesses of one run so that the ratio is fair on a noisy machine.

    python benchmarks/perf/bench_reset.py --ref dee5fb6 --json benchmarks/results/perf/bench_reset.json
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import time
from pathlib import Path

from dexart_lite.utils import provenance, sibling_script

ROOT = Path(__file__).resolve().parents[2]
harness = sibling_script(__file__, "_harness")  # benchmarks/_harness.py: runs of another commit
TASKS = ("faucet", "bucket", "laptop", "toilet")

MEASURE = """
import json, sys, time
from dexart_lite.envs import make
task, resets = sys.argv[1], int(sys.argv[2])
env = make(task, num_points=512)
for seed in range(20):  # warm-up: every object loaded once (PyBullet's file cache)
    env.reset(seed=seed)
start = time.perf_counter()
for seed in range(resets):
    env.reset(seed=1000 + seed)
print(json.dumps({"ms_per_reset": (time.perf_counter() - start) / resets * 1e3}))
"""


def measure(package_root: Path, task: str, resets: int) -> float:
    """ms per reset of ``task`` with the ``dexart_lite`` found under ``package_root``."""
    return harness.run_in_checkout(package_root, MEASURE, task, str(resets))["ms_per_reset"]


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks", "resets", "rounds", "ref", "json")
    args = parser.parse_args(argv)
    roots = {"this": ROOT}
    start = time.time()
    results = {}
    with harness.git_worktree(ROOT, args.ref) if args.ref else contextlib.nullcontext() as ref_root:
        if ref_root is not None:
            roots["ref"] = ref_root
        for task in args.tasks:
            samples = {k: [] for k in roots}
            for _ in range(args.rounds):
                for key, root in roots.items():
                    samples[key].append(measure(root, task, args.resets))
            row = {f"{k}_ms_per_reset": sorted(v)[len(v) // 2] for k, v in samples.items()}
            if args.ref:
                row["ratio_this_over_ref"] = row["this_ms_per_reset"] / row["ref_ms_per_reset"]
            results[task] = row
            print(task, {k: round(v, 2) for k, v in row.items()}, flush=True)
    report = {"tasks": results, "resets": args.resets, "rounds": args.rounds, "ref": args.ref,
              "this_commit": subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                            capture_output=True, text=True).stdout.strip(),
              "wall_time_s": time.time() - start,
              **provenance(__file__, argv)}
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
    return report


if __name__ == "__main__":
    main()
