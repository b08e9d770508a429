"""When does the scripted expert reach each stage? The first step of stage 2, of stage 3 and of success per episode.

    python benchmarks/experts/stage_timeline.py --task bucket --split seen --episodes-per-object 1 \\
        --json benchmarks/results/experts/stage_timeline_bucket.json

The noise-free expert on the state observation (the physics, and so the timeline, does not depend on what is
observed), the ``solve`` episodes (episode ``k`` of object ``i`` reset with seed ``seed + 1000 k + i``, the seeds
``rl/curriculum.find_demos`` draws its demonstrations from). A step count ``n`` means "after ``n`` control steps"
(0: at the reset; None: never). It says how far a reverse curriculum's frontier, which starts one step before the
first success, must move back before the learner starts ahead of each stage.

Written to ``--json``: task, split, seed, episodes (object, seed, success, first_stage2, first_stage3,
first_success, steps), summary (per key: min, median, max over the episodes that reach it, and how many do),
command, machine.
"""

from __future__ import annotations

import argparse

import numpy as np

from dexart_lite.envs import make
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.experts.solve import solve_episodes
from dexart_lite.rollout import run_episodes
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

KEYS = ("first_stage2", "first_stage3", "first_success")


def first(stages: list[int], stage: int) -> int | None:
    """Steps taken when the episode first is in ``stage`` or above (``stages``: the stage after each step)."""
    return next((t + 1 for t, s in enumerate(stages) if s >= stage), None)


def timeline(task: str, split: str, episodes_per_object: int, seed: int) -> list[dict]:
    env = make(task, split=split, observation="state", **({"max_episode_steps": 40} if fast_mode() else {}))
    names = env.unwrapped.objects.names[:1] if fast_mode() else env.unwrapped.objects.names
    try:
        results = run_episodes(ScriptedPolicy(env), env, solve_episodes(names, episodes_per_object, seed))
    finally:
        env.close()
    return [{"object": r["object"], "seed": r["seed"], "success": r["success"],
             "first_stage2": first(r["stages"], 2), "first_stage3": first(r["stages"], 3),
             "first_success": r["success_step"], "steps": r["steps"]} for r in results]


def summarise(episodes: list[dict]) -> dict:
    out = {}
    for key in KEYS:
        values = [e[key] for e in episodes if e[key] is not None]
        out[key] = {"reached": len(values), "of": len(episodes),
                    **({"min": int(np.min(values)), "median": float(np.median(values)), "max": int(np.max(values))}
                       if values else {})}
    return out


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "split", "seed", "json", task="bucket", episodes_per_object=1)
    args = parser.parse_args(argv)
    episodes = timeline(args.task, args.split, args.episodes_per_object, args.seed)
    result = {"task": args.task, "split": args.split, "seed": args.seed, "episodes": episodes,
              "summary": summarise(episodes), **provenance(__file__, argv)}
    for key, s in result["summary"].items():
        span = f"{s['min']} / {s['median']:.0f} / {s['max']}" if s["reached"] else "-"
        print(f"{key:14s} reached in {s['reached']} of {s['of']} episodes; min / median / max step {span}")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
