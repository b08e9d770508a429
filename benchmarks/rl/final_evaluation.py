"""A reported cell, evaluated once on the test seed: the expert, the students or the RL policies of one task.

    python benchmarks/rl/final_evaluation.py --task laptop --column expert
    python benchmarks/rl/final_evaluation.py --task laptop --column rl --jobs 2 \\
        --source laptop_cloud_student_anchored_floor_flat_b16k.json \\
        --checkpoints 0=b3693a9:benchmarks/results/rl/curriculum/checkpoints/laptop_cloud_student_anchored_floor_flat_b16k_s0/checkpoint.pt \\
                      1=b3693a9:benchmarks/results/rl/curriculum/checkpoints/laptop_cloud_student_anchored_floor_flat_b16k_s1/checkpoint.pt

The protocol is ``dexart_lite.rl.evaluate``'s: deterministic actions from the true reset, 10 episodes per seen and
per unseen object, at the test seed (``TEST_SEEDS``), which no choice ever reads. Each cell's ± is the standard error
over its training seeds, with the per-seed values beside it (the expert has no training seed: its se is the
episodes' object-stratified one). Checkpoints are files or ``REV:path`` in git history (extracted under ``--cache``,
as ``checkpoint_sweep.py`` does); every evaluation is cached beside its checkpoint.

Written to ``benchmarks/results/test/<task>_<column>.json``: task, column, source (the candidate the headline rule
chose, whose checkpoints these are: the README's table shows this file only while the rule still chooses it), the
protocol (env seed, episodes per object), per split the cell (mean, se, per_seed, training_seeds, episode_se, the
per-object success of each seed, and ``templates``: success per object template and, for the unseen split, its
held-out-band and held-out-template halves, read from the objects' metadata), the checkpoints, and the simulator
steps behind the cell per training seed: ``frames`` (the learner's own online frames), ``guide_frames`` (steps the
scripted guide took before handing over, in guided starts), ``demo_frames`` (demonstrations and DAgger rounds, the
student's distillation included), and ``steps_in_all`` (their sum); command and machine.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.checkpoint import load_checkpoint
from dexart_lite.rl.evaluate import (EPISODES_PER_OBJECT, TEST_SEEDS, by_template, evaluate_expert, over_seeds,
                                     protocol_evaluation, split_stats)
from dexart_lite.utils import benchmark_results, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__).parent / "test"
harness = sibling_script(__file__, "_harness")
COLUMNS = ("expert", "student", "rl", "rl_state")
SPLITS = ("seen", "unseen")


def simulator_steps(payload: dict, student: dict | None = None) -> dict:
    """The simulator steps behind one checkpoint (``payload``, with its ``history``): the learner's online frames,
    the guide's steps before each hand-over, and the demonstration steps (a distilled student's expert and student
    frames; an RL run's own demonstrations plus, given ``student``, the distillation of the student it started
    from)."""
    history = payload["history"]
    if history and "expert_frames" in history[-1]:  # a distilled student: every step of it is distillation
        demo = int(history[-1]["expert_frames"] + history[-1]["student_frames"])
        return {"frames": 0, "guide_frames": 0, "demo_frames": demo, "steps_in_all": demo}
    guide = sum(int(row.get("guide_steps", 0)) for row in history)
    demos = payload.get("demos") if isinstance(payload.get("demos"), dict) else {}
    demo = int(demos.get("frames", 0)) + (simulator_steps(student)["demo_frames"] if student else 0)
    frames = int(payload["frames"])
    return {"frames": frames, "guide_frames": guide, "demo_frames": demo, "steps_in_all": frames + guide + demo}


def expert_cell(task: str, episodes: int) -> dict:
    """The scripted expert on both splits at the test seed (no training seed: one value per split)."""
    out = {}
    for split in SPLITS:
        result = evaluate_expert(task, split, episodes, TEST_SEEDS[0])
        stats = split_stats(result)
        out[split] = {**over_seeds([stats["success"]]), "training_seeds": [], "episode_se": [stats["se"]],
                      "objects": stats["objects"], "templates": by_template(task, split, stats["objects"])}
    return out


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    column: str = field(default="expert", metadata={"choices": list(COLUMNS), "help": "the cell's column"})
    checkpoints: list[str] = field(default_factory=list, metadata={"help": "SEED=CHECKPOINT per training seed (a file "
                                   "or REV:path in git history); not for the expert"})
    source: str | None = field(default=None, metadata={"help": "the candidate these checkpoints are, as the headline "
                               "rule names it (`python benchmarks/rl/curriculum_table.py --choices` prints each "
                               "task's); not for the expert"})
    students: list[str] = field(default_factory=list, metadata={"help": "SEED=CHECKPOINT: the students the RL "
                                "checkpoints started from, counted in the cell's demonstration steps (not evaluated)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", required=("task",))
    add_config_arguments(parser, Flags, overrides=False, required=("column",))
    harness.options(parser, eval_episodes=EPISODES_PER_OBJECT)
    harness.options(parser, "jobs")
    harness.options(parser, cache=Path("runs/final_evaluation"))
    harness.options(parser, "json", helps={"json": f"default {RESULTS.name}/<task>_<column>.json"})
    args = parser.parse_args(argv)
    if (args.column == "expert") == bool(args.checkpoints) or (args.column == "expert") == bool(args.source):
        raise ValueError("--checkpoints and --source are needed for every column but the expert's, and only there")
    path = args.json or RESULTS / f"{args.task}_{args.column}.json"
    out = {"task": args.task, "column": args.column, "source": args.source, "env_seed": TEST_SEEDS[0],
           "episodes_per_object": args.eval_episodes}
    if args.column == "expert":
        out.update(expert_cell(args.task, args.eval_episodes))
    else:
        resolve = sibling_script(__file__, "checkpoint_sweep").resolve
        specs = dict(parse(text) for text in args.checkpoints)
        files = {seed: resolve(spec, args.cache) for seed, spec in specs.items()}
        payloads = {seed: load_checkpoint(f) for seed, f in files.items()}
        wrong = sorted({p["config"]["task"] for p in payloads.values()} - {args.task})
        if wrong:
            raise ValueError(f"--task {args.task} but the checkpoints are of {', '.join(wrong)}")
        cell = protocol_evaluation(files, "test", args.jobs, args.eval_episodes)
        students = {seed: load_checkpoint(resolve(spec, args.cache)) for seed, spec in map(parse, args.students)}
        out.update({split: cell[split] for split in SPLITS}, checkpoints=specs,
                   students={seed: spec for seed, spec in map(parse, args.students)},
                   steps={seed: simulator_steps(p, students.get(seed)) for seed, p in payloads.items()})
    out.update(provenance(__file__, argv))
    write_json(path, out)
    for split in SPLITS:
        c = out[split]
        print(f"{args.task} {args.column} {split}: {c['mean']:.2f} ± {c['se']:.2f} "
              f"({' / '.join(f'{v:.2f}' for v in c['per_seed'])})")
    print(f"wrote {path}")
    return out


def parse(text: str) -> tuple[int, str]:
    seed, sep, spec = text.partition("=")
    if not sep or not seed.isdigit():
        raise ValueError(f"expected SEED=CHECKPOINT (a file or REV:path), got {text!r}")
    return int(seed), spec


if __name__ == "__main__":
    main()
