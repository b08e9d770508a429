"""What a guided start costs, and what skipping the guide's camera renders saves.

    python benchmarks/rl/bench_guide.py --task laptop --h 100 --repeats 5 --json benchmarks/results/rl/curriculum/bench_guide.json

A start-state curriculum (``rl/curriculum.GuidedStart``) replays the guide for ``h`` steps at every reset. On the
point-cloud observation each guide step would also render the depth camera, which nobody reads;
``guide_render=False`` (the default of ``dexart-lite train``) renders only the last one. Measured here: the
seconds of one guided reset with and without those renders, alternately in one process (``--repeats``
rounds, the best of each), on the same seeds, and the state observation's for comparison (no camera at all).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.rl.curriculum import GuidedStart
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

LEVEL = {"schedule": "uniform", "horizon": 250}


def timed_start(env: GuidedStart, seed: int, h: int) -> float:
    tick = time.perf_counter()
    env.start(seed, h)
    return time.perf_counter() - tick


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    h: int = field(default=100, metadata={"min": 0, "help": "guide steps per start"})
    repeats: int = field(default=5, metadata={"min": 1, "help": "rounds of one timed guided start per variant (the "
                                                               "best of each)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "json")
    args = parser.parse_args(argv)
    if fast_mode():
        args.h, args.repeats = min(args.h, 5), 1
    envs = {"cloud_render_every_step": GuidedStart(make(args.task), LEVEL, guide_render=True),
            "cloud_render_last_step": GuidedStart(make(args.task), LEVEL, guide_render=False),
            "state": GuidedStart(make(args.task, observation="state"), LEVEL)}
    best = {name: float("inf") for name in envs}
    for r in range(args.repeats):  # alternately, so load changes hit every variant alike
        for name, env in envs.items():
            best[name] = min(best[name], timed_start(env, r, args.h))
    for env in envs.values():
        env.close()
    result = {"task": args.task, "h": args.h, "repeats": args.repeats,
              "seconds_per_start": {k: round(v, 4) for k, v in best.items()},
              "guide_steps_per_s": {k: round(args.h / v, 1) for k, v in best.items()},
              "render_skip_speedup": round(best["cloud_render_every_step"] / best["cloud_render_last_step"], 2),
              **provenance(__file__, argv)}
    print(result)
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
