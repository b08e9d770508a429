"""Env throughput per task (random actions, 1 and 2 processes) and memory over many resets.

For each task, side by side in one run:

* ``steps_per_s``: ``env.step`` with random actions in this process (reset when an episode ends);
* ``steps_per_s_2proc``: the total of two such loops in two worker processes at once;
* ``vs_physics_only``: the full step's cost over the physics-only control step
  (action -> IK + motor targets -> frame_skip sub-steps), measured in the same process.

``reset_rss_growth_mb``: resident memory after ``--resets`` resets cycling through every laptop
(seen and unseen objects in one env), minus the memory after a warm-up of one cycle.

With ``--ref COMMIT``, each task's 1-process rate is also measured for this checkout and for a ``git
worktree`` of that commit, alternately in fresh subprocesses of the same run (``vs_ref``: this / ref);
speed-ups are claimed from this ratio, never from figures taken on different days or machines.

    python benchmarks/perf/bench_envs.py --json benchmarks/results/perf/bench_envs.json
    python benchmarks/perf/bench_envs.py --ref 2f696c9 --resets 0 --json benchmarks/results/perf/bench_envs_vs_2f696c9.json
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path

import psutil

import dexart_lite
from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.rollout import parallel_step_rates, random_actions, step_rate
from dexart_lite.utils import provenance, sibling_script, write_json

ROOT = Path(__file__).resolve().parents[2]
harness = sibling_script(__file__, "_harness")  # benchmarks/_harness.py: runs of another commit
# The 1-process loop of ``rollout.step_rate`` as a script, with only the API every commit has (``make``, step).
MEASURE = """
import json, sys, time
import numpy as np
from dexart_lite.envs import make
task, steps = sys.argv[1], int(sys.argv[2])
rng = np.random.default_rng(0)
actions = rng.uniform(-1, 1, size=(steps, 22)) * np.r_[[0.3] * 6, [1.0] * 16]
env = make(task)
env.reset(seed=0)
start = time.perf_counter()
for a in actions:
    _, _, terminated, truncated, _ = env.step(a)
    if terminated or truncated:
        env.reset()
print(json.dumps({"steps_per_s": steps / (time.perf_counter() - start)}))
"""


def physics_rate(task: str, steps: int, seed: int = 0) -> float:
    """Physics-only control steps per second (what env.step does before reading the state)."""
    env = make(task).unwrapped
    env.reset(seed=seed)
    actions = random_actions(steps, seed)
    start = time.perf_counter()
    for a in actions:
        q, _ = env.sim.joint_states(env.robot.body, env.robot.joints)
        env.robot.apply_action(a, q)
        for i in range(env.frame_skip):
            env.robot.track_arm((i + 1) * env.sim.dt)
            env.sim.step()
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def two_process_rate(task: str, steps: int) -> float:
    """Total env steps per second of two worker processes stepping at the same time."""
    return float(sum(parallel_step_rates(task, steps, 2)))


def reset_rss_growth_mb(resets: int) -> float:
    """Memory growth over ``resets`` resets cycling through all laptops, after one warm-up cycle."""
    names = [o.name for s in ("seen", "unseen") for o in dexart_lite.objects.list_objects("laptop", s)]
    env = make("laptop", object_names=names)
    process = psutil.Process()
    for i, name in enumerate(names):  # warm-up: every object visited once
        env.reset(seed=i, options={"object": name})
    before = process.memory_info().rss
    for i in range(resets):
        env.reset(seed=i, options={"object": names[i % len(names)]})
    growth = (process.memory_info().rss - before) / 2**20
    env.close()
    return growth


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    two_process: bool = field(default=True, metadata={"help": "also measure two worker processes stepping at once"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks", "steps", "rounds", resets=2000,
                    helps={"resets": "resets of the memory check (0: skip it)"})
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "ref", "json", helps={"ref": "an earlier commit whose 1-process rate is measured side by "
                                                         "side"})
    args = parser.parse_args(argv)

    tasks = {}
    for task in args.tasks:
        full, physics = [], []
        for _ in range(args.rounds):  # interleaved, so drifts in machine load hit both alike
            full.append(step_rate(task, args.steps))
            physics.append(physics_rate(task, args.steps))
        full_rate, physics_rate_ = statistics.median(full), statistics.median(physics)
        two = two_process_rate(task, args.steps) if args.two_process else None
        tasks[task] = {"steps_per_s": full_rate, "steps_per_s_2proc": two, "vs_physics_only": physics_rate_ / full_rate}
    if args.ref:
        with harness.git_worktree(ROOT, args.ref) as ref_root:
            for task in args.tasks:
                rates = {"this": [], "ref": []}
                for _ in range(args.rounds):
                    for key, root in (("this", ROOT), ("ref", ref_root)):
                        rate = harness.run_in_checkout(root, MEASURE, task, str(args.steps))["steps_per_s"]
                        rates[key].append(rate)
                this, ref = statistics.median(rates["this"]), statistics.median(rates["ref"])
                tasks[task].update({"steps_per_s_subprocess": this, "ref_steps_per_s": ref, "vs_ref": this / ref})
    result = {"tasks": tasks, "reset_rss_growth_mb": reset_rss_growth_mb(args.resets) if args.resets else None,
              "resets": args.resets, "steps": args.steps, "ref": args.ref,
              **provenance(__file__, argv)}
    print("| task | env steps/s (1 process) | env steps/s (2 processes, total) | full step / physics-only step |")
    print("|---|---|---|---|")
    for task, r in tasks.items():
        two = f"{r['steps_per_s_2proc']:.0f}" if r["steps_per_s_2proc"] else "-"
        print(f"| {task} | {r['steps_per_s']:.0f} | {two} | {r['vs_physics_only']:.2f} |")
    if args.ref:
        print(f"\n| task | this checkout (subprocess) | {args.ref} | this / ref |\n|---|---|---|---|")
        for task, r in tasks.items():
            print(f"| {task} | {r['steps_per_s_subprocess']:.0f} | {r['ref_steps_per_s']:.0f} | {r['vs_ref']:.2f} |")
    if args.resets:
        print(f"\nmemory growth over {args.resets} resets through all laptops: {result['reset_rss_growth_mb']:.1f} MB")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
