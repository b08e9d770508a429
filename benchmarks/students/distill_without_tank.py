"""Would the toilet students open the tankless template C if some training toilets showed no tank? A diagnostic.

    python benchmarks/students/distill_without_tank.py --seeds 0 1 --prob 0.5 --jobs 2

Why: no toilet policy opens the unseen toilets of template C (tankless, squarish), and on seen toilets with the tank
cut out of the cloud the policies fail as often (``tank_ablation.py``). Is the missing tank what stops them, or the
squarish lid? Here the students are distilled again with the tank hidden in some of their training episodes.

An oracle, not a recipe for the benchmark: it uses what the unseen split showed (C has no tank), so its unseen
figure is no blind test, and it reads the simulator to find the tank. What it answers is what more varied seen
toilets would buy.

Each seed is the headline toilet student (the settings of ``benchmarks/results/students/distill_toilet_episodes2x.json``
that ``benchmarks/rl/curriculum_runs.py``'s student step uses, 3 evaluation episodes per object at env seed 100),
distilled in a process whose ``dexart_lite.envs.make`` is wrapped so that every env built for the demonstrations and
the DAgger rounds hides its toilet's tank above the seat (``tank_ablation.erase_tank``) in each episode with
probability ``--prob``; the expert, which reads the simulator, is unaffected. Evaluation sees the toilets as they are
(``rl.evaluate`` bound ``make`` when it was imported, before the wrap; checked). Run folders
``runs/curriculum/toilet_cloud_student_notank_s<seed>`` (a finished one is read back).

Written to ``benchmarks/results/students/distill_toilet_notank.json``: prob, per seed the success seen / unseen and
per template, wall time, frames; the means; command, machine.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite import objects as objects_lib
from dexart_lite.imitation.distill import DistillConfig
from dexart_lite.study import run_arm
from dexart_lite.utils import benchmark_results, fast_mode, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")
STUDENT = RESULTS / "distill_toilet_episodes2x.json"  # curriculum_runs.STUDENTS["toilet"]


def student_config(seed: int, runs: Path, threads: int) -> DistillConfig:
    overrides = json.loads(STUDENT.read_text())["overrides"]
    overrides.update(task="toilet", seed=seed, eval_episodes=3, progress=False, threads=threads,
                     out=str(runs / f"toilet_cloud_student_notank_s{seed}"))
    if fast_mode():  # a smoke run of the script itself, not evidence
        overrides.update(num_points=64, max_episode_steps=10, demo_episodes_per_object=1, rounds=1,
                         episodes_per_round=1, epochs=1, epochs_per_round=1, eval_episodes=1,
                         objects=objects_lib.list_objects("toilet", "seen")[0].name)
    return DistillConfig(**overrides)


def distil(cfg: DistillConfig, prob: float) -> dict:
    """One student whose collection envs hide the tank with probability ``prob`` per episode (in this process)."""
    import dexart_lite.envs as envs
    import dexart_lite.rl.evaluate as evaluate

    original, erase_tank = envs.make, sibling_script(__file__, "tank_ablation").erase_tank
    if evaluate.make_gym_env is not original:
        raise RuntimeError("rl.evaluate must build its envs with the unwrapped make")
    built = [0]

    def make(*args, **kwargs):
        env = original(*args, **kwargs)
        erase_tank(env.unwrapped, prob, seed=cfg.seed * 1000 + built[0])  # each env its own draws
        built[0] += 1
        return env

    envs.make = make
    try:
        result = run_arm(cfg)
    finally:
        envs.make = original
    rows = sibling_script(__file__, "success_by_template").by_template([Path(cfg.out)])["rows"]  # from its own evaluations
    per_template = {f"{r['split']}_{r['template']}": r["success"] for r in rows if r["template"] != "all"}
    return {"seed": cfg.seed, "run": cfg.out, "seen_success": result["seen_success"],
            "unseen_success": result["unseen_success"], "per_template": per_template,
            "expert_frames": result["expert_frames"], "student_frames": result["student_frames"],
            "wall_time_s": round(result["wall_time_s"], 1)}


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    prob: float = field(default=0.5, metadata={"min": 0.0,
                                               "help": "probability that a training episode hides the tank"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, seeds=[0, 1])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "jobs", runs=Path("runs/curriculum"), json=RESULTS / "distill_toilet_notank.json",
                    helps={"jobs": "seeds distilled at once (one torch thread each if > 1)"})
    args = parser.parse_args(argv)
    if not 0.0 <= args.prob <= 1.0:
        raise ValueError(f"--prob must be a probability in [0, 1], got {args.prob}")
    cfgs = [student_config(seed, args.runs, 1 if args.jobs > 1 else 0) for seed in args.seeds]
    # with --jobs > 1 each seed runs in a spawned worker with its own wrapped make; here the wrap is undone after each
    per_seed = list(harness.each(distil, [{"cfg": cfg, "prob": args.prob} for cfg in cfgs], jobs=args.jobs,
                                 desc="seeds"))
    out = {"task": "toilet", "prob": args.prob, "student_settings": str(STUDENT.name), "per_seed": per_seed,
           "seen_success": float(np.mean([r["seen_success"] for r in per_seed])),
           "unseen_success": float(np.mean([r["unseen_success"] for r in per_seed])),
           "per_template": {k: float(np.mean([r["per_template"][k] for r in per_seed])) for k in per_seed[0]["per_template"]},
           "eval_episodes_per_object": cfgs[0].eval_episodes, "eval_seed": cfgs[0].eval_seed,
           **provenance(__file__, argv)}
    write_json(args.json, out)
    print(json.dumps({k: out[k] for k in ("seen_success", "unseen_success", "per_template")}, indent=1))
    print(f"wrote {args.json}")
    return out


if __name__ == "__main__":
    main()
