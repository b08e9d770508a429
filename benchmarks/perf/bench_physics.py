"""Cheaper physics, checked: env speed and the scripted solvers' success for each physics setting.

Physics is ~64 % of a Laptop env step (``bench_sim.json``). Its two knobs that leave the task alone are the
constraint solver's iteration count (``solver_iterations``, default 50) and the number of physics
sub-steps per control step (``frame_skip``, default 10 sub-steps of 4 ms). The control step stays 40 ms
(25 Hz, DexArt's) in every setting: ``dt = 0.04 s / frame_skip``. A setting is written
``ITERATIONSxFRAME_SKIP``, e.g. ``20x10`` (20 solver iterations, 10 sub-steps of 4 ms) or ``50x5``
(50 iterations, 5 sub-steps of 8 ms); the first one given is the baseline (the defaults, ``50x10``).

For each setting, in one run:

* ``steps_per_s``: ``env.step`` with random actions (bench_envs' loop), per task; the settings take turns
  in every round and the medians are reported, so a busy machine slows them all alike; ``vs_baseline``
  is the ratio to the first setting;
* ``solvers``: the scripted solvers' success on every seen and unseen object (``--episodes-per-object``,
  evaluation seeds as ``dexart-lite solve``), and its difference from the baseline measured here. Issue
  15's contract for a physics change: every task and split within ``--tolerance`` (0.03) of the baseline
  (``solvers_within_tolerance``); ``solvers_no_lower_per_task``: per task, whether no split fell by more
  than the tolerance (a setting may suit some tasks and not others). The success rates do not depend
  on the machine's load; the speeds do: measure those alone.

    python benchmarks/perf/bench_physics.py --settings 50x10 30x10 20x10 50x5 --json benchmarks/results/perf/bench_physics.json
    python benchmarks/perf/bench_physics.py --settings 50x10 20x10 --no-solvers   # speed only, a few seconds per task
    python benchmarks/perf/bench_physics.py --no-speed --json benchmarks/results/perf/bench_physics_solvers.json  # success only
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import dataclass, field

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs.base import physics_setting
from dexart_lite.experts.solve import solve
from dexart_lite.rollout import step_rate
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

BASELINE = "50x10"  # the env's defaults: 50 solver iterations, 10 sub-steps of 4 ms


def speeds(tasks: list[str], settings: list[str], steps: int, rounds: int) -> dict:
    """Median steps/s per task and setting; the settings take turns in each round."""
    out = {}
    for task in tasks:
        rates: dict[str, list[float]] = {s: [] for s in settings}
        for _ in range(rounds):
            for setting in settings:
                rates[setting].append(step_rate(task, steps, **physics_setting(setting)))
        base = statistics.median(rates[settings[0]])
        out[task] = {s: {"steps_per_s": statistics.median(r), "vs_baseline": statistics.median(r) / base}
                     for s, r in rates.items()}
    return out


def solver_success(tasks: list[str], settings: list[str], episodes: int, tolerance: float,
                   max_episode_steps: int | None = None) -> dict:
    """The solvers' success per task, split and setting; each setting's difference from the first one."""
    out = {}
    for task in tasks:
        out[task] = {}
        for split in ("seen", "unseen"):
            rates = {}
            for setting in settings:
                physics = physics_setting(setting)
                if max_episode_steps:
                    physics["max_episode_steps"] = max_episode_steps
                rates[setting] = solve(task, split, episodes, seed=0, progress=False, env_kwargs=physics)["success_rate"]
            base = rates[settings[0]]
            out[task][split] = {s: {"success_rate": r, "minus_baseline": r - base,
                                    "within_tolerance": abs(r - base) <= tolerance,
                                    "no_lower": r - base >= -tolerance} for s, r in rates.items()}
    return out


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    settings: list[str] = field(default_factory=lambda: [BASELINE, "30x10", "20x10", "50x5"],
                                metadata={"help": "ITERATIONSxFRAME_SKIP, the first one the baseline"})
    speed: bool = field(default=True, metadata={"help": "measure the steps/s of every setting (alone on the machine: "
                                                        "these are timings)"})
    solvers: bool = field(default=True, metadata={"help": "also run the scripted solvers on every seen and unseen "
                                                          "object per setting"})
    tolerance: float = field(default=0.03, metadata={"min": 0.0, "help": "allowed change of a solver's success"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "steps", "rounds")
    harness.options(parser, "episodes_per_object")
    harness.options(parser, "json")
    args = parser.parse_args(argv)
    for setting in args.settings:
        physics_setting(setting)
    max_episode_steps = None
    if fast_mode():  # a smoke run of the script, not evidence
        args.steps, args.rounds, args.episodes_per_object, max_episode_steps = 5, 1, 1, 5

    start = time.perf_counter()
    result = {"settings": {s: physics_setting(s) for s in args.settings}, "baseline": args.settings[0],
              "speed": speeds(args.tasks, args.settings, args.steps, args.rounds) if args.speed else None}
    if args.solvers:
        result["solvers"] = solver_success(args.tasks, args.settings, args.episodes_per_object, args.tolerance,
                                           max_episode_steps)
        result["solvers_within_tolerance"] = {
            s: all(row[s]["within_tolerance"] for task in result["solvers"].values() for row in task.values())
            for s in args.settings}
        result["solvers_no_lower_per_task"] = {
            s: {task: all(row[s]["no_lower"] for row in splits.values()) for task, splits in result["solvers"].items()}
            for s in args.settings}
    result.update({"steps": args.steps, "rounds": args.rounds, "episodes_per_object": args.episodes_per_object,
                   "tolerance": args.tolerance, "wall_time_s": time.perf_counter() - start,
                   **provenance(__file__, argv)})

    print("| task | " + " | ".join(f"{s} steps/s" for s in args.settings) + " |\n|---|" + "---|" * len(args.settings))
    for task, row in (result["speed"] or {}).items():
        print(f"| {task} | " + " | ".join(f"{row[s]['steps_per_s']:.0f} (x{row[s]['vs_baseline']:.2f})"
                                          for s in args.settings) + " |")
    if args.solvers:
        print("\n| task / split | " + " | ".join(f"{s} solver success" for s in args.settings) + " |\n|---|"
              + "---|" * len(args.settings))
        for task, splits in result["solvers"].items():
            for split, row in splits.items():
                print(f"| {task} / {split} | " + " | ".join(
                    f"{row[s]['success_rate']:.2f} ({row[s]['minus_baseline']:+.2f})" for s in args.settings) + " |")
        print("\nwithin the tolerance on every task and split: " + ", ".join(
            f"{s}: {'yes' if ok else 'NO'}" for s, ok in result["solvers_within_tolerance"].items()))
        print("no split lower by more than the tolerance, per task: " + "; ".join(
            f"{s}: " + ", ".join(t for t, ok in tasks.items() if ok) for s, tasks in result["solvers_no_lower_per_task"].items()))
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
