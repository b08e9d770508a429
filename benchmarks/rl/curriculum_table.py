"""The tables of RL from the experts, generated from the committed JSON (never typed by hand).

    python benchmarks/rl/curriculum_table.py            # print the tables
    python benchmarks/rl/curriculum_table.py --write    # refresh them in docs/results/rl_from_experts.md and README.md

Seven tables, each between ``<!-- NAME -->`` and ``<!-- /NAME -->`` markers in the files it goes into:

* ``curriculum-runs`` (docs/results/rl_from_experts.md): every ``benchmarks/results/rl/curriculum/*.json`` run
  set: task, observation, recipe, seeds, online frames and demonstration frames per seed, seen / unseen success
  from the true reset (mean ± std over the seeds, then each seed), evaluation episodes per object, training wall
  time per seed.
* ``paired-eval`` (docs/results/rl_from_experts.md): each point-cloud RL run set against the students it started
  from, both evaluated again side by side with more episodes (``benchmarks/results/rl/paired_eval.json``, written by
  ``benchmarks/rl/paired_eval.py``): per split student -> RL and RL - student ± its standard error.
* ``clone-capacity`` (docs/results/rl_from_experts.md): the DAgger clone of each network size from
  ``benchmarks/results/rl/curriculum/clone_capacity_*.json`` (``benchmarks/rl/clone_capacity.py``).
* ``targets`` (docs/results/rl_from_experts.md): each task's headline cells against the targets: DexArt's Table 2
  and the students + 0.10 (point clouds, held out), >= 0.8 seen within 1M frames (the state diagnostic), and the
  best held-out success of any run set within 2M frames.
* ``rl-headline`` (README.md): task × scripted expert / distilled point-cloud student / RL, with DexArt's Table 2
  (no pretraining) beside them. Which run set fills a cell is chosen by a rule, not by hand (``headline``:
  ``dexart_lite.rl.evaluate.choose_headline``, the best validation success on seen objects within the frame
  budget); a cell shows its test-seed evaluation (``benchmarks/results/test/<task>_<column>.json``, written by
  ``benchmarks/rl/final_evaluation.py`` for that very choice) where there is one, else its validation figure,
  marked so.
* ``zoo`` (README.md): the policies shipped in ``dexart_lite/zoo/`` and the success each reproduces (its manifest,
  written by ``benchmarks/students/zoo_build.py`` together with ``benchmarks/results/students/zoo.json``).
* ``scaling`` (docs/results/performance.md): collection and plain env steps against workers on each machine measured
  (``SCALING``: ``benchmarks/results/perf/bench_scaling*.json``, written by ``benchmarks/perf/bench_scaling.py``).

``tests/test_docs_tables.py`` fails when a table in a file differs from what this script generates.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.evaluate import check_phase_seed, choose_headline, over_seeds

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
DOC = ROOT / "docs" / "results" / "rl_from_experts.md"
PAIRED = RESULTS / "rl" / "paired_eval.json"  # benchmarks/rl/paired_eval.py
README = ROOT / "README.md"
TEST = RESULTS / "test"  # benchmarks/rl/final_evaluation.py: each reported cell once on the test seed
TASKS = ("faucet", "bucket", "laptop", "toilet")
PAPER_NO_PRETRAIN = {"faucet": (0.30, 0.28), "bucket": (0.51, 0.56), "laptop": (0.81, 0.41), "toilet": (0.71, 0.46)}
def load(path: Path) -> dict:
    return json.loads(path.read_text())


def spread(values: list[float]) -> str:
    return f"{np.mean(values):.2f} ± {np.std(values):.2f}" if len(values) > 1 else f"{values[0]:.2f}"


def runs_table() -> str:
    rows = ["| task | obs | recipe | seeds | online frames / seed | demo frames / seed | seen success | "
            "unseen success | eval eps / object | training time / seed | JSON |", "|" + "---|" * 11]
    for path in sorted((RESULTS / "rl" / "curriculum").glob("*.json")):
        result = load(path)
        if "recipe" not in result or not result.get("per_seed"):
            continue  # not a run of RL (e.g. a `--students-only` distillation, whose students are zoo entries)
        seeds = result["per_seed"]
        seen, unseen = [r["seen_success"] for r in seeds], [r["unseen_success"] for r in seeds]
        frames = " / ".join(f"{r['frames'] / 1000:.0f}k" for r in seeds)
        demo = " / ".join(f"{r['demo_frames'] / 1000:.1f}k" for r in seeds)
        each = {name: " / ".join(f"{v:.2f}" for v in values) for name, values in (("seen", seen), ("unseen", unseen))}
        minutes = " / ".join(f"{r['wall_time_s'] / 60:.0f} min" for r in seeds)
        rows.append(f"| {result['task']} | {result['obs']} | `{result['recipe']}` | {len(seeds)} | {frames} | {demo} "
                    f"| **{spread(seen)}** ({each['seen']}) | **{spread(unseen)}** ({each['unseen']}) "
                    f"| {result['eval_episodes_per_object']} | {minutes} | [{path.name}](../../benchmarks/results/rl/curriculum/{path.name}) |")
    return "\n".join(rows)


def paired_table() -> str:
    """Each point-cloud RL run set against the students it started from, evaluated again side by side with more
    episodes (benchmarks/rl/paired_eval.py): per split the seeds' mean student -> RL, RL - student ± se, each seed."""
    if not PAIRED.exists():
        return "Not measured yet: `python benchmarks/rl/paired_eval.py --jobs 2` (needs the runs' checkpoints)."
    result = load(PAIRED)
    rows = [f"| task | recipe | seeds | RL frames / seed | seen: student -> RL | seen: RL - student (each seed) "
            f"| unseen: student -> RL | unseen: RL - student (each seed) |", "|" + "---|" * 8]
    for e in result["summary"]:
        seeds = [r for r in result["runs"] if (r["task"], r["recipe"]) == (e["task"], e["recipe"])]
        cells = []
        for split in ("seen", "unseen"):
            each = " / ".join(f"{r['delta'][split]['value']:+.2f}" for r in seeds)
            cells.append(f"{e[split]['student']:.2f} -> {e[split]['rl']:.2f} "
                         f"| **{e[split]['delta']:+.2f} ± {e[split]['delta_se']:.2f}** ({each})")
        frames = " / ".join(f"{f / 1000:.0f}k" for f in e["rl_frames"])
        rows.append(f"| {e['task']} | `{e['recipe']}` | {len(seeds)} | {frames} | {cells[0]} | {cells[1]} |")
    return "\n".join(rows)


def clone_table() -> str:
    """Per task and network: the DAgger clone's success from the true reset (benchmarks/rl/clone_capacity.py)."""
    rows = ["| task | obs | network (state MLP / heads) | seeds | DAgger rounds | samples / seed "
            "| clone's success in its DAgger rounds | eval episodes / object | seen success | unseen success | JSON |",
            "|" + "---|" * 11]
    for path in sorted((RESULTS / "rl" / "curriculum").glob("clone_capacity_*.json")):
        result = load(path)
        for arch in result["summary"]:
            runs = [r for r in result["per_run"] if r["arch"] == arch]
            seen, unseen = [r["seen_success"] for r in runs], [r["unseen_success"] for r in runs]
            rounds = " / ".join(", ".join(f"{v:.2f}" for v in r["dagger_success"]) for r in runs)
            samples = " / ".join(f"{r['samples'] / 1000:.0f}k" for r in runs)
            each = {name: " / ".join(f"{v:.2f}" for v in values) for name, values in (("seen", seen), ("unseen", unseen))}
            network = f"`{arch}` ({runs[0]['state_hidden']} / {runs[0]['head'].replace(',', 'x')})"
            rows.append(f"| {result['task']} | {result['obs']} | {network} | {len(runs)} | {result['rounds']} | {samples} "
                        f"| {rounds} | {result['eval_episodes_per_object']} "
                        f"| **{spread(seen)}** ({each['seen']}) | **{spread(unseen)}** ({each['unseen']}) "
                        f"| [{path.name}](../../benchmarks/results/rl/curriculum/{path.name}) |")
    return "\n".join(rows)


def paired_summary() -> list[dict]:
    """The run sets' held-out re-evaluations (``paired_eval.json``'s ``summary``; empty before it is measured)."""
    return load(PAIRED)["summary"] if PAIRED.exists() else []


def student_candidates(task: str) -> list[dict]:
    """Every committed student set of ``task`` (``bench_distill`` and ``curriculum_runs --students-only`` JSONs) with
    its own evaluation, made at a validation seed: {"name" (its JSON under benchmarks/results), "frames" (distillation
    steps per seed), "validation": per-seed seen and unseen success}."""
    out = []
    for path in [*sorted((RESULTS / "students").glob(f"distill_{task}*.json")),
                 *sorted((RESULTS / "rl" / "curriculum").glob(f"{task}_cloud_student*.json"))]:
        result = load(path)
        if "recipe" in result or result.get("task") != task or not result.get("per_seed"):
            continue  # an RL run set, or not a student set of this task
        check_phase_seed("validation", result.get("eval_seed", 100))  # distill's default evaluation seed is 100
        seeds = result["per_seed"]
        frames = [r.get("frames", r.get("expert_frames", 0) + r.get("student_frames", 0)) for r in seeds]
        out.append({"name": str(path.relative_to(RESULTS)), "frames": frames,
                    "validation": {s: [r[f"{s}_success"] for r in seeds] for s in ("seen", "unseen")}})
    return out


def rl_candidates(task: str) -> list[dict]:
    """The point-cloud RL run sets of ``task`` re-evaluated side by side with their students (``paired_eval.json``,
    10 episodes per object at a validation seed): name (the run set's JSON), RL frames per seed, per-seed success."""
    if not PAIRED.exists():
        return []
    paired = load(PAIRED)
    check_phase_seed("validation", paired["eval_seed"])
    out = []
    for e in paired["summary"]:
        if e["task"] == task:
            seeds = [r for r in paired["runs"] if (r["task"], r["recipe"]) == (task, e["recipe"])]
            out.append({"name": f"{task}_cloud_{e['recipe']}.json", "frames": e["rl_frames"], "entry": e,
                        "validation": {s: [r["rl"][s]["success"] for r in seeds] for s in ("seen", "unseen")}})
    return out


def state_candidates(task: str) -> list[dict]:
    """The state-observation RL run sets of ``task`` with their own evaluation (at a validation seed)."""
    out = []
    for path in sorted((RESULTS / "rl" / "curriculum").glob(f"{task}_state_*.json")):
        result = load(path)
        if "recipe" not in result or not result.get("per_seed"):
            continue
        check_phase_seed("validation", result["eval_seed"])
        seeds = result["per_seed"]
        out.append({"name": path.name, "frames": [r["frames"] for r in seeds],
                    "validation": {s: [r[f"{s}_success"] for r in seeds] for s in ("seen", "unseen")}})
    return out


def headline(task: str) -> dict:
    """The rule's choice for each column of ``task`` (None where there is no candidate): the student set, the
    point-cloud RL run set within ``FRAME_BUDGET`` and the state run set within ``STATE_TARGET``'s frames."""
    def pick(candidates: list[dict], budget: float) -> dict | None:
        return choose_headline(candidates, budget) if any(max(c["frames"]) <= budget for c in candidates) else None

    return {"student": pick(student_candidates(task), float("inf")), "rl": pick(rl_candidates(task), FRAME_BUDGET),
            "rl_state": pick(state_candidates(task), STATE_TARGET[1])}


def test_result(task: str, column: str, source: str | None) -> dict | None:
    """The final evaluation of a cell (``benchmarks/results/test/<task>_<column>.json``) if it evaluated ``source``
    (the chosen candidate; the expert has none), else None."""
    path = TEST / f"{task}_{column}.json"
    if not path.exists():
        return None
    result = load(path)
    return result if result.get("source") == source else None


def cell(task: str, column: str, chosen: dict | None, link: str) -> str:
    """``seen / unseen`` of a chosen candidate: its test-seed evaluation (mean ± se over seeds) where there is one,
    else its validation figure, marked "validation"."""
    if chosen is None:
        return "not yet ([why](docs/results/rl_from_experts.md))"
    final = test_result(task, column, chosen["name"])
    if final is not None:
        values = " / ".join(f"{final[s]['mean']:.2f} ± {final[s]['se']:.2f}" for s in ("seen", "unseen"))
        steps = [v["steps_in_all"] for v in final.get("steps", {}).values()]
        in_all = f", {np.mean(steps) / 1e6:.2f}M simulator steps in all per seed" if steps else ""
        return f"[{values}](benchmarks/results/test/{task}_{column}.json) (test seed{in_all})"
    values = " / ".join(f"{over_seeds(chosen['validation'][s])['mean']:.2f}" for s in ("seen", "unseen"))
    return f"[{values}]({link}) (validation)"


def headline_table() -> str:
    rows = ["| task | scripted expert (privileged) | distilled point-cloud student | RL on point clouds | "
            "RL on the state (diagnostic) | DexArt Table 2 (RL, no pretraining) |", "|---|---|---|---|---|---|"]
    for task in TASKS:
        chosen = headline(task)
        final = test_result(task, "expert", None)
        if final is not None:
            expert = (f"[{final['seen']['mean']:.2f} / {final['unseen']['mean']:.2f}]"
                      f"(benchmarks/results/test/{task}_expert.json) (test seed)")
        else:
            solved = [load(RESULTS / "experts" / f"solve_{task}_{s}.json")["success_rate"] for s in ("seen", "unseen")]
            expert = f"[{solved[0]:.2f} / {solved[1]:.2f}](benchmarks/results/experts/solve_{task}_seen.json)"
        student, rl, state = chosen["student"], chosen["rl"], chosen["rl_state"]
        student_cell = cell(task, "student", student, f"benchmarks/results/{student['name']}" if student else "")
        if student:
            student_cell += f" `{Path(student['name']).stem}`, {len(student['frames'])} seeds"
        rl_cell_text = cell(task, "rl", rl, "benchmarks/results/rl/paired_eval.json")
        if rl:
            frames = np.mean(rl["frames"])
            rl_cell_text += (f" `{rl['entry']['recipe']}`, {frames / 1000:.0f}k frames, {len(rl['frames'])} seeds, from "
                             f"students at {rl['entry']['seen']['student']:.2f} / {rl['entry']['unseen']['student']:.2f}")
        state_cell = cell(task, "rl_state", state, f"benchmarks/results/rl/curriculum/{state['name']}" if state else "")
        if state:
            state_cell += f" `{load(RESULTS / 'rl' / 'curriculum' / state['name'])['recipe']}`, " \
                          f"{np.mean(state['frames']) / 1000:.0f}k frames, {len(state['frames'])} seeds"
        rows.append(f"| {task} | {expert} | {student_cell} | {rl_cell_text} | {state_cell} "
                    f"| {PAPER_NO_PRETRAIN[task][0]:.2f} / {PAPER_NO_PRETRAIN[task][1]:.2f} |")
    return "\n".join(rows)


TARGET_MARGIN = 0.10  # the target (b): RL >= its DAgger student + 0.10 on both splits
STATE_TARGET = (0.8, 1_000_000)  # target (a), the state diagnostic: >= 0.8 seen success within 1M frames per seed
FRAME_BUDGET = 2_000_000  # target (b): point clouds, within 2M online frames per seed


def verdict(values: tuple[float, float], targets: tuple[float, float]) -> str:
    """``"0.81 / 0.41: met / missed"``: each split's target and whether the value reaches it (compared to 1e-9, so
    that a success of 11/110 meets a target of 0.00 + 0.10 that floating point puts a hair above it)."""
    marks = " / ".join("met" if v >= t - 1e-9 else "missed" for v, t in zip(values, targets))
    return f"{targets[0]:.2f} / {targets[1]:.2f}: {marks}"


def targets_table() -> str:
    """Each task's headline RL cells against the targets: on point clouds (held out, ``paired_eval.json``) DexArt's
    Table 2 and the students it started from + 0.10 (both on the same held-out resets), and the README's student
    cell + 0.10 (its own evaluation, 3 episodes per object); the best held-out success of any run set of the task
    within the frame budget; on the state observation >= 0.8 seen success within 1M frames."""
    paired = paired_summary()
    rows = ["| task | RL on point clouds at validation seed 1000 (run set, frames / seed) | DexArt Table 2 | its students + 0.10 "
            "(same resets) | the README's student cell + 0.10 | best of any run set within 2M frames | "
            "RL on the state: seen >= 0.8 within 1M frames |", "|---|---|---|---|---|---|---|"]
    for task in TASKS:
        chosen = headline(task)
        entry = chosen["rl"]["entry"] if chosen["rl"] else None
        student = chosen["student"]
        readme_student = tuple(over_seeds(student["validation"][s])["mean"] + TARGET_MARGIN for s in ("seen", "unseen")) \
            if student else (math.nan, math.nan)
        within = [e for e in paired if e["task"] == task and max(e["rl_frames"]) <= FRAME_BUDGET]
        best = " / ".join(
            f"{max(e[split]['rl'] for e in within):.2f} (`{max(within, key=lambda e: e[split]['rl'])['recipe']}`)"
            for split in ("seen", "unseen")) if within else "-"
        if entry is None:
            cloud = ["not yet", "-", "-", "-"]
        else:
            values = (entry["seen"]["rl"], entry["unseen"]["rl"])
            frames = " / ".join(f"{f / 1000:.0f}k" for f in entry["rl_frames"])
            own = (entry["seen"]["student"] + TARGET_MARGIN, entry["unseen"]["student"] + TARGET_MARGIN)
            cloud = [f"{values[0]:.2f} / {values[1]:.2f} (`{entry['recipe']}`, {frames})",
                     verdict(values, PAPER_NO_PRETRAIN[task]), verdict(values, own), verdict(values, readme_student)]
        if chosen["rl_state"]:
            state = load(RESULTS / "rl" / "curriculum" / chosen["rl_state"]["name"])
            ok = state["seen_success"] >= STATE_TARGET[0] and max(r["frames"] for r in state["per_seed"]) <= STATE_TARGET[1]
            state_cell = (f"{state['seen_success']:.2f} at {state['frames'] / 1000:.0f}k (`{state['recipe']}`): "
                          + ("met" if ok else "missed"))
        else:
            state_cell = "not a target"
        rows.append(f"| {task} | " + " | ".join(cloud) + f" | {best} | {state_cell} |")
    return "\n".join(rows)


def zoo_table() -> str:
    """The shipped policies (dexart_lite/zoo/manifest.json, written by benchmarks/students/zoo_build.py with zoo.json)."""
    path = ROOT / "dexart_lite" / "zoo" / "manifest.json"
    manifest = load(path)["policies"] if path.exists() else {}
    rows = ["| `--ckpt` | trained by | frames (its training data) | seed | seen / unseen success (3 eps per object, env seed 100) |",
            "|---|---|---|---|---|"]
    for task, e in manifest.items():
        command = re.sub(r" --note .*$", "", e["training_command"] or "")  # the note is in the manifest, not the table
        rows.append(f"| `zoo:{task}` | {e['trainer']} (`{command}`) | {e['frames'] / 1000:.0f}k | {e['seed']} "
                    f"| [{e['seen_success']:.2f} / {e['unseen_success']:.2f}](benchmarks/results/students/zoo.json) |")
    return "\n".join(rows)


PERFORMANCE = ROOT / "docs" / "results" / "performance.md"
SCALING = ("bench_scaling.json", "bench_scaling_h200_16cores.json")  # benchmarks/results/perf, one per machine


def scaling_table() -> str:
    """``bench_scaling.py``'s figures, a row per machine and worker count (frames/s with the policy acting; "-": not
    measured there)."""
    rows = ["| machine | timed frames per setting | workers | `process` collector, frames/s | `ray` collector, frames/s "
            "| plain `env.step` in N processes, steps/s (per process) |", "|---|---|---|---|---|---|"]
    for name in SCALING:
        d = load(RESULTS / "perf" / name)
        machine = f"[{d['machine']['cores']}-core {d['machine']['cpu'].replace('(R)', '')}](benchmarks/results/perf/{name})"
        for w in sorted({int(k) for k in d["plain_env"]} | {int(k) for b in d["collection"].values() for k in b}):
            cell = lambda backend: f"{d['collection'][backend][str(w)]:,.0f}" if str(w) in d["collection"].get(backend, {}) else "-"  # noqa: E731
            env = d["plain_env"].get(str(w))
            rows.append(f"| {machine} | {d['frames_per_setting']:,} | {w} | {cell('process')} | {cell('ray')} | "
                        + (f"{env['total']:,.0f} ({env['per_process']:,.0f})" if env else "-") + " |")
    return "\n".join(rows).replace("](benchmarks/", "](../../benchmarks/")


TABLES = {"curriculum-runs": (DOC, runs_table), "paired-eval": (DOC, paired_table), "clone-capacity": (DOC, clone_table),
          "targets": (DOC, targets_table),
          "rl-headline": (README, headline_table), "zoo": (README, zoo_table), "scaling": (PERFORMANCE, scaling_table)}


def block(text: str, name: str) -> re.Match | None:
    return re.search(rf"<!-- {name} -->\n(.*?)<!-- /{name} -->", text, flags=re.S)


def stale_tables() -> list[str]:
    """Names of the tables whose text in their file differs from the generated one (or is missing)."""
    stale = []
    for name, (path, make) in TABLES.items():
        found = block(path.read_text(), name) if path.exists() else None
        if found is None or found.group(1) != make() + "\n":
            stale.append(name)
    return stale


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    write: bool = field(default=False, metadata={"help": "replace the tables in their files"})
    choices: bool = field(default=False, metadata={"help": "print the headline rule's choice per task and column (the "
                          "--source of benchmarks/rl/final_evaluation.py) and nothing else"})


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    args = parser.parse_args(argv)
    if args.choices:
        for task in TASKS:
            for column, chosen in headline(task).items():
                print(f"{task} {column}: {chosen['name'] if chosen else '-'}")
        return
    tables = {name: (path, make()) for name, (path, make) in TABLES.items()}
    for name, (path, table) in tables.items():
        print(f"{name} ({path}):\n{table}\n")
        if args.write and block(path.read_text(), name) is None:  # checked for every file before any is written
            raise ValueError(f"{path} has no <!-- {name} --> ... <!-- /{name} --> block to fill")
    for name, (path, table) in tables.items() if args.write else ():
        text = path.read_text()
        path.write_text(text.replace(block(text, name).group(0), f"<!-- {name} -->\n{table}\n<!-- /{name} -->"))


if __name__ == "__main__":
    main()
