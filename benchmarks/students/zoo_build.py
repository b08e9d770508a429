"""Ship trained policies: copy a checkpoint into ``dexart_lite/zoo/<task>.pt``, measure it, write its manifest entry.

    python benchmarks/students/zoo_build.py --policy laptop=runs/curriculum/laptop_cloud_student_s1/checkpoint.pt \
        --source laptop=benchmarks/results/rl/curriculum/laptop_cloud_student_guarded.json

For each ``TASK=CHECKPOINT``: the weights, config, sizes and history of the checkpoint (not its optimizer) are
written to ``dexart_lite/zoo/<task>.pt`` (at most 2 MB), loaded back strictly and evaluated as ``dexart-lite eval
--ckpt zoo:<task>`` does (deterministic actions from the true reset, ``--eval-episodes`` per seen and unseen object,
env seed 100). The measurements go to ``benchmarks/results/students/zoo.json`` (per task: file, bytes, trainer, frames,
seed, the training command (from ``--source``, the results JSON the run belongs to, or ``--training-command``), the
machine, ``--note``, seen_success, unseen_success, eval_episodes_per_object, eval_seed, mean_max_stage; the command
and machine of this script),
and the same entries to ``dexart_lite/zoo/manifest.json``, which the package reads. Tasks not named keep their
entries.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

from dexart_lite.cli import add_config_arguments
from dexart_lite import zoo
from dexart_lite.rl.checkpoint import REQUIRED, load_checkpoint, save_checkpoint
from dexart_lite.rl.evaluate import evaluate_checkpoint
from dexart_lite.utils import benchmark_results, check_choice, fast_mode, provenance, sibling_script, write_json
from dexart_lite.registration import TASKS

RESULTS = benchmark_results(__file__) / "zoo.json"
harness = sibling_script(__file__, "_harness")


def pairs(values: list[str], what: str) -> dict[str, str]:
    """``["laptop=PATH", ...]`` -> ``{"laptop": "PATH"}``, task names checked."""
    out = {}
    for value in values:
        task, sep, path = value.partition("=")
        if not sep:
            raise ValueError(f"--{what} takes TASK=PATH, got {value!r}")
        check_choice("task", task, TASKS)
        out[task] = path
    return out


def ship(task: str, source: Path, folder: Path) -> Path:
    """The checkpoint at ``source`` without its optimizer, as ``folder/<task>.pt``; refused over 2 MB."""
    payload = load_checkpoint(source)
    if payload["config"]["task"] != task:
        raise ValueError(f"{source} is a {payload['config']['task']} policy, not {task}")
    path = save_checkpoint(folder / f"{task}.pt", {k: payload[k] for k in (*REQUIRED, "trainer") if k in payload})
    if path.stat().st_size > zoo.MAX_BYTES:
        path.unlink()
        raise ValueError(f"{source} is {path.stat().st_size / 1e6:.1f} MB without its optimizer; the zoo takes "
                         f"<= {zoo.MAX_BYTES / 2**20:.0f} MB per policy")
    return path


def measure(task: str, path: Path, episodes: int, seed: int, training: dict | None) -> dict:
    payload = load_checkpoint(path)
    evals = {split: evaluate_checkpoint(path, split, episodes, seed) for split in ("seen", "unseen")}
    cfg = payload["config"]
    return {"task": task, "file": path.name, "bytes": path.stat().st_size,
            "trainer": payload.get("trainer", cfg.get("algo", "ppo")), "frames": payload["frames"],
            "seed": cfg.get("seed"), "encoder": cfg.get("encoder"),
            "training_command": (training or {}).get("command"), "training_machine": (training or {}).get("machine"),
            "seen_success": evals["seen"]["success_rate"], "unseen_success": evals["unseen"]["success_rate"],
            "mean_max_stage": {s: evals[s]["mean_max_stage"] for s in evals},
            "eval_episodes_per_object": episodes, "eval_seed": seed}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    policy: list[str] = field(default_factory=list, metadata={"help": "TASK=CHECKPOINT, the policies to ship"})
    source: list[str] = field(default_factory=list, metadata={"help": "TASK=JSON: the results JSON of the run each "
                              "checkpoint comes from (its command and machine)"})
    training_command: list[str] = field(default_factory=list, metadata={"help": "TASK=COMMAND: the command that "
                                        "trained a policy, where its --source records only the step that collected "
                                        "finished runs into it (bench_distill.py --collect)"})
    zoo: Path = field(default=zoo.FOLDER, metadata={"help": "where the checkpoints and manifest go"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, required=("policy",))
    harness.options(parser, eval_episodes=3)
    harness.options(parser, seed=100, helps={"seed": "evaluation env seed (as dexart-lite eval)"})
    harness.options(parser, "note", json=RESULTS,
                    helps={"note": "a line stored with each policy of this call (which run, why)"})
    args = parser.parse_args(argv)
    if fast_mode() and (args.json == RESULTS or args.zoo == zoo.FOLDER):
        raise ValueError("fast mode writes smoke results: pass --json and --zoo elsewhere")
    policies, sources = pairs(args.policy, "policy"), pairs(args.source, "source")
    commands = pairs(args.training_command, "training-command")
    manifest_path = args.zoo / zoo.MANIFEST.name
    entries = json.loads(manifest_path.read_text())["policies"] if manifest_path.exists() else {}
    for task, source in policies.items():
        path = ship(task, Path(source), args.zoo)
        training = json.loads(Path(sources[task]).read_text()) if task in sources else None
        if task in commands:
            training = {**(training or {}), "command": commands[task]}
        entries[task] = measure(task, path, args.eval_episodes, args.seed, training)
        if args.note:
            entries[task]["note"] = args.note
        print(f"zoo:{task}: {entries[task]['bytes'] / 1e6:.2f} MB, seen {entries[task]['seen_success']:.2f}, "
              f"unseen {entries[task]['unseen_success']:.2f}")
    result = {"policies": dict(sorted(entries.items())), **provenance(__file__, argv)}
    write_json(args.json, result)
    write_json(manifest_path, {"policies": result["policies"],
                               "evidence": "benchmarks/results/students/zoo.json (written with this file by benchmarks/students/zoo_build.py)"})
    return result


if __name__ == "__main__":
    main()
