"""Which unseen objects do students fail on? Success per object template, from finished runs.

    python benchmarks/students/success_by_template.py --runs runs/distill_toilet_dagger_episodes2x_s0 \
        runs/distill_toilet_dagger_episodes2x_s1 runs/distill_toilet_dagger_episodes2x_s2 \
        --json benchmarks/results/students/success_by_template_toilet.json

Every category's seen objects come from templates A and B; half of its unseen objects come from the
held-out template C (a shape family no training object has, e.g. tankless square toilets), the
others from A / B with one parameter in a held-out band (``urdf/objects/README.md``). A student's
unseen success mixes the two kinds of novelty; this script separates them. It reads each run's
``eval_seen.json`` / ``eval_unseen.json`` (``dexart-lite distill`` or ``bench_distill.py`` folders,
or a PPO run's; ``--eval heldout_{split}_e10_seed1000.json`` reads ``paired_eval.py``'s held-out evaluations
instead, and with ``--evaluate`` makes those that are missing) and the object catalog, and writes per
split and template (and ``all``, the whole split): the success of each run (mean over that template's
objects, each object weighted by its episodes), their mean and std, the objects and the episodes; and
per object the success of each run. The unseen split also gets the row ``held_out_bands``: its objects of
the templates the seen split has (each with a parameter in a held-out band), the half that DexArt's own
unseen split resembles (new instances of the shape families it trains on). Without ``--evaluate`` no
simulation: it takes seconds.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite import objects as objects_lib
from dexart_lite.cli import add_config_arguments
from dexart_lite.utils import provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

SPLITS = ("seen", "unseen")


@dataclass
class Flags:
    """This script's own flags (``--runs``, ``--eval``, ``--evaluate``); the shared ones come from the harness."""

    runs: list[Path] = field(default_factory=list, metadata={"help": "finished run folders (one per seed)"})
    eval: str = field(default="eval_{split}.json",
                      metadata={"help": "the evaluation file in each run folder, {split} for seen / unseen"})
    evaluate: bool = field(default=False, metadata={
        "help": "with --eval heldout_{split}_e<N>_seed<S>.json: first evaluate each run's checkpoint.pt where that "
                "file is missing (rl.evaluate.evaluate_many: N deterministic episodes per object from the true "
                "reset, env seed S), --jobs at a time"})


def read_run(run: Path, pattern: str = "eval_{split}.json") -> dict[str, dict]:
    """``{split: eval json}`` of a finished run folder (``pattern`` names the file per split); a one-line error if
    one is missing."""
    evals = {}
    for split in SPLITS:
        path = run / pattern.format(split=split)
        if not path.is_file():
            raise FileNotFoundError(f"{run} has no {path.name}: not a finished distill or train run "
                                    "(or not evaluated that way)")
        evals[split] = json.loads(path.read_text())
    return evals


def by_template(runs: list[Path], pattern: str = "eval_{split}.json") -> dict:
    """The per-template and per-object success of ``runs`` (see the module docstring)."""
    evals = [read_run(run, pattern) for run in runs]
    tasks = {e["seen"]["task"] for e in evals}
    if len(tasks) != 1:
        raise ValueError(f"the runs are of different tasks: {sorted(tasks)}")
    task = tasks.pop()
    templates = {info.name: info.template for split in SPLITS for info in objects_lib.list_objects(task, split)}
    seen_templates = {info.template for info in objects_lib.list_objects(task, "seen")}
    rows, per_object = [], {}
    for split in SPLITS:
        groups: dict[str, list[str]] = defaultdict(list)
        for name in evals[0][split]["objects"]:
            groups[templates[name]].append(name)
        groups["all"] = list(evals[0][split]["objects"])  # the split's overall success, same weighting
        if split == "unseen":  # the held-out-band half alone (as rl.evaluate.by_template)
            groups["held_out_bands"] = [name for name in evals[0][split]["objects"]
                                        if templates[name] in seen_templates]
        for template, names in sorted(groups.items()):
            per_run, episodes = [], 0
            for e in evals:
                objs = e[split]["objects"]
                n = sum(objs[name]["episodes"] for name in names)
                per_run.append(sum(objs[name]["success_rate"] * objs[name]["episodes"] for name in names) / n)
                episodes += n
            rows.append({"split": split, "template": template, "objects": len(names), "episodes": episodes,
                         "success": float(np.mean(per_run)), "success_std": float(np.std(per_run)),
                         "per_run": per_run})
        for name in evals[0][split]["objects"]:
            per_object[name] = {"split": split, "template": templates[name],
                                "per_run": [e[split]["objects"][name]["success_rate"] for e in evals]}
    return {"task": task, "runs": [str(run) for run in runs], "eval_file": pattern, "rows": rows,
            "per_object": per_object}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, required=("runs",))
    harness.options(parser, "json", helps={"json": "where to write the result (default: print only)"})
    harness.options(parser, "jobs", helps={"jobs": "with --evaluate: evaluations side by side (processes)"})
    args = parser.parse_args(argv)
    if "{split}" not in args.eval:
        raise ValueError(f"--eval must contain {{split}} (e.g. eval_{{split}}.json), got {args.eval!r}")
    if args.evaluate:
        found = re.fullmatch(r"heldout_\{split\}_e(\d+)_seed(\d+)\.json", args.eval)
        if not found:
            raise ValueError(f"--evaluate writes heldout_{{split}}_e<N>_seed<S>.json files; got --eval {args.eval!r}")
        from dexart_lite.rl.evaluate import evaluate_many

        evaluate_many([(run / "checkpoint.pt", split) for run in args.runs for split in SPLITS],
                      int(found.group(1)), int(found.group(2)), jobs=args.jobs)
    result = by_template(args.runs, args.eval)
    print(f"| {result['task']} | template | objects | episodes | success (mean ± std over {len(args.runs)} runs) |")
    print("|---|---|---|---|---|")
    for row in result["rows"]:
        print(f"| {row['split']} | {row['template']} | {row['objects']} | {row['episodes']} | "
              f"{row['success']:.2f} ± {row['success_std']:.2f} ({' / '.join(f'{v:.2f}' for v in row['per_run'])}) |")
    if args.json:
        write_json(args.json, {**result, **provenance(__file__, argv)})
        print(f"wrote {args.json}")
    return result


if __name__ == "__main__":
    main()
