"""Resident memory of a PPO training process, batch by batch, with and without handing freed memory back to the OS.

    python benchmarks/perf/bench_train_memory.py --json benchmarks/results/perf/bench_train_memory.json
    python benchmarks/perf/bench_train_memory.py --batches 4 --task laptop      # a quick look

Why: a 100-minute faucet run on point clouds (``curriculum_runs.py``, in-process collection) ended at 6.8 and 8.0 GB
resident per process. Two PPO runs of the ``cpu`` preset from random weights (``--task``, point clouds, one
in-process env, 1 torch thread each, no evaluation) train side by side in two processes, the same seed and
settings, one with ``trim_memory=True`` (the default: glibc's ``malloc_trim`` after every batch,
``utils.release_freed_memory``) and one without. Each batch's row of the run's history has ``rss_mb``, read right
after the update (and the trim, where on).

Written to ``--json``: batches, frames_per_batch, task, per arm (``trim`` / ``no_trim``): ``rss_mb`` (one per
batch), ``growth_mb_per_batch`` (least-squares slope over the batches after the first ``--skip``), ``final_mb``,
``fps`` (mean frames per second over the batches after the first, beside the other arm, so only the ratio is a
figure); ``fps_ratio`` (trim / no_trim), command, machine. ``--jobs 1`` runs the arms one after the other in this
process, for smoke runs only.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl import ppo
from dexart_lite.utils import fast_mode, process_pool, provenance, sibling_script, sigterm_interrupts, write_json

harness = sibling_script(__file__, "_harness")


def arm(job: tuple) -> list[dict]:
    """One training run (``trim`` on or off); its history rows."""
    task, batches, trim = job
    with tempfile.TemporaryDirectory() as out:
        cfg = ppo.preset("cpu", task=task, obs="cloud", frames=batches * 4000, workers=1, eval_episodes=0,
                         progress=False, threads=1, checkpoint_every=10**6, out=out, trim_memory=trim, seed=0)
        if fast_mode():  # a smoke run of the script, not evidence
            cfg = dataclasses.replace(cfg, frames_per_batch=200, minibatch=100, epochs=1, num_points=64,
                                      max_episode_steps=30, frames=batches * 200)
        ppo.train(cfg)
        return ppo.load_checkpoint(f"{out}/{ppo.CHECKPOINT}")["history"]


def summary(history: list[dict], skip: int) -> dict:
    rss = [row["rss_mb"] for row in history]
    later = np.arange(len(rss))[skip:]
    slope = float(np.polyfit(later, np.asarray(rss)[skip:], 1)[0]) if len(later) >= 2 else float("nan")
    return {"rss_mb": rss, "growth_mb_per_batch": slope, "final_mb": rss[-1],
            "fps": float(np.mean([row["fps"] for row in history[1:]] or [history[0]["fps"]]))}


@dataclasses.dataclass
class Flags:
    """This script's own flags (its --jobs means the arms side by side, not the harness's runs at once)."""

    batches: int = dataclasses.field(default=16, metadata={"min": 1, "help": "PPO batches of 4,000 frames per arm"})
    skip: int = dataclasses.field(default=3, metadata={"min": 0,
                                                       "help": "batches left out of the growth's fit (start-up)"})
    jobs: int = dataclasses.field(default=2, metadata={
        "choices": [1, 2], "help": "2: the arms side by side in two processes (the figures); 1: one after the other "
                                   "in this process (a smoke run: the second arm's memory starts from the first's)"})


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    harness.options(parser, task="faucet")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "json")
    args = parser.parse_args(argv)

    batches = 2 if fast_mode() else args.batches
    jobs = [(args.task, batches, True), (args.task, batches, False)]
    if args.jobs == 2:
        with sigterm_interrupts(), process_pool(2) as pool:  # the two arms side by side; a kill stops both
            trim, no_trim = pool.map(arm, jobs)
    else:
        trim, no_trim = map(arm, jobs)
    skip = min(args.skip, batches - 1)
    result = {"task": args.task, "batches": batches, "frames_per_batch": trim[0]["frames"],
              "trim": summary(trim, skip), "no_trim": summary(no_trim, skip), **provenance(__file__, argv)}
    result["fps_ratio"] = result["trim"]["fps"] / result["no_trim"]["fps"]
    for name in ("trim", "no_trim"):
        r = result[name]
        print(f"{name:8s} final {r['final_mb']:.0f} MB, growth {r['growth_mb_per_batch']:+.1f} MB/batch, "
              f"rss per batch {' '.join(f'{v:.0f}' for v in r['rss_mb'])}")
    print(f"frames per second, trim / no_trim (side by side): {result['fps_ratio']:.3f}")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
