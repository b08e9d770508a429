"""Every results table in docs/ and the README, generated from the committed JSON (never typed by hand).

    python docs/tables.py            # print every table
    python docs/tables.py --write    # rewrite each table between its markers in its file

A table lives between ``<!-- NAME -->`` and ``<!-- /NAME -->`` in its file; ``--write`` refuses to write anything when
a file lacks a table's markers. The tables of RL from the experts come from ``benchmarks/rl/curriculum_table.py``
(its ``TABLES``, loaded from here; ``python benchmarks/rl/curriculum_table.py --write`` refreshes those alone); the
others are this file's ``TABLES``, each made by a function that names the JSON it reads (all under
``benchmarks/results/``). Where a table holds a figure that no committed JSON has (DexArt's, or a measurement
without a JSON), the figure is a constant here with a comment saying where it comes from.
``tests/test_docs_generated.py`` fails when a table in a file differs from what this script generates.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import statistics
import sys
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
RES = ROOT / "docs" / "results"
CURRICULUM_TABLE = ROOT / "benchmarks" / "rl" / "curriculum_table.py"
TASKS = ("faucet", "bucket", "laptop", "toilet")
SPLITS = ("seen", "unseen")
# DexArt's Table 2, PPO without pretraining (seen, unseen), ~15M frames: quoted from the paper, not measured here
PAPER_NO_PRETRAIN = {"faucet": (0.30, 0.28), "bucket": (0.51, 0.56), "laptop": (0.81, 0.41), "toilet": (0.71, 0.46)}
PAPER_LAPTOP_SEG = (0.92, 0.60)  # DexArt's Table 2, Laptop, segmentation-pretrained PointNet (seen, unseen)


# ---------------------------------------------------------------------------------------------------- helpers


def load(rel: str) -> dict:
    """A committed JSON, by its path under benchmarks/results/."""
    return json.loads((RESULTS / rel).read_text())


def link(rel: str, text: str = "JSON", folder: Path = RES) -> str:
    """A markdown link from a page in ``folder`` to benchmarks/results/``rel`` (which must exist)."""
    if not (RESULTS / rel).exists():
        raise FileNotFoundError(RESULTS / rel)
    up = "../" * len(folder.relative_to(ROOT).parts)
    return f"[{text}]({up}benchmarks/results/{rel})"


def mean(values) -> float:
    return statistics.fmean(values)


def std(values) -> float:
    """The population standard deviation (numpy's default, as the JSON's ``*_std`` fields)."""
    return statistics.pstdev(values) if len(values) > 1 else 0.0


def se(values) -> float:
    """The standard error of the mean over runs (sample std / sqrt(n); 0 for one run), the protocol's ±."""
    return statistics.stdev(values) / len(values) ** 0.5 if len(values) > 1 else 0.0


def f2(x: float) -> str:
    """Two decimals, halves rounded up as a reader would (0.625, 75 of 120 episodes, is 0.63)."""
    return str(Decimal(repr(x)).quantize(Decimal("0.01"), rounding=ROUND_HALF_UP)).replace("-0.00", "0.00")


def pm(m: float, s: float) -> str:
    return f"{f2(m)} ± {f2(s)}"


def spread(values, strong: bool = False) -> str:
    """``mean ± std (each / value)`` over seeds, the mean ± std in bold if ``strong``."""
    return f"{bold(pm(mean(values), std(values)), strong)} ({' / '.join(f2(v) for v in values)})"


def bold(text: str, on: bool = True) -> str:
    return f"**{text}**" if on else text


def span(values, digits: int = 1, unit: str = "") -> str:
    """``lo-hi`` of the values rounded to ``digits`` (a single value where they round alike)."""
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return (lo if lo == hi else f"{lo}-{hi}") + unit


def kilo(values) -> str:
    """Frames as ``6.5-6.7k`` (to 0.1k below 20k, to 1k above)."""
    digits = 1 if max(values) < 20_000 else 0
    return span([v / 1000 for v in values], digits, "k")


def table(header: list[str], rows: list[list[str]]) -> str:
    """A markdown table (an empty cell written ``| |``)."""
    def line(cells: list[str]) -> str:
        return "|" + "|".join(f" {c} " if c else " " for c in cells) + "|"

    return "\n".join([line(header), "|" + "---|" * len(header), *(line(row) for row in rows)])


def machine_name(result: dict) -> str:
    """``<CPU> VM`` from a JSON's ``machine`` record, "(R)" and "Processor" dropped (only performance.md names
    machines)."""
    cpu = result["machine"]["cpu"].replace("(R)", "").replace(" Processor", "")
    return f"{cpu} VM"


# ---------------------------------------------------------------------------------------------------- experts.md

EXPERTS = RES / "experts.md"


def expert_success() -> str:
    """``solve_<task>_<split>.json`` (``dexart-lite solve``, 3 episodes per object, seed 0)."""
    rows = []
    for task in TASKS:
        runs = {s: load(f"experts/solve_{task}_{s}.json") for s in SPLITS}
        weakest = " / ".join(f2(min(runs[s]["success_per_object"].values())) for s in SPLITS)
        counts = [str(len(runs[s]["success_per_object"])) for s in SPLITS]
        if task == TASKS[0]:
            counts[0] += " objects"  # the first row says what the number counts
        rows.append([task, *(f"{f2(runs[s]['success_rate'])} ({n})" for s, n in zip(SPLITS, counts)), weakest])
    return table(["task", "seen success", "unseen success", "weakest object (seen / unseen)"], rows)


def noise_cell(results: dict | list[dict], sigma: float) -> str:
    """``seen / unseen`` success at action-noise ``sigma``: mean ± std over the seeds' rows of one result or of
    several pooled (no ± where nothing succeeded or there is one seed)."""
    results = [results] if isinstance(results, dict) else results
    cells = []
    for split in SPLITS:
        rates = [r["success_rate"] for result in results for r in result["rows"]
                 if r["split"] == split and r["action_noise"] == sigma]
        cells.append(f2(mean(rates)) if len(rates) == 1 or mean(rates) == 0 else pm(mean(rates), std(rates)))
    return " / ".join(cells)


# The first, phase-machine toilet expert under noise (seed 0; seen / unseen at std 0.3 and 0.5): measured before the
# expert was replaced, its JSON not committed
TOILET_PHASE_MACHINE = ("0.69 / 0.82", "0.18 / 0.18")


def expert_noise() -> str:
    """``exploration_noise_<task>.json`` (``benchmarks/experts/exploration_noise.py``, 3 seeds)."""
    rows = []
    for task, label, strong in (("faucet", "faucet", True), ("laptop", "laptop, `FeedbackLidSolver`", False),
                                ("toilet", "toilet, `FeedbackLidSolver`", False)):
        rel = f"experts/exploration_noise_{task}.json"
        result = load(rel)
        rows.append([f"{label} ({link(rel)})", *(bold(noise_cell(result, s), strong) for s in (0.3, 0.5))])
    rows.append(["toilet, the earlier phase-machine expert (seed 0)", *TOILET_PHASE_MACHINE])
    return table(["expert", "std 0.3, seen / unseen", "std 0.5, seen / unseen"], rows)


# The fingertip-hook bucket expert without noise (seed 0, `dexart-lite solve`): measured before the overhand expert
# replaced it; that solve JSON is not committed (solve_bucket_*.json are the overhand expert's)
HOOK_NOISELESS = "0.91 / 1.00 (solve, seed 0)"


def bucket_expert_noise() -> str:
    """``exploration_noise_bucket.json`` (overhand, 3 seeds) and ``exploration_noise_bucket_seeds34.json`` (the
    same expert at std 0.1 on two more seeds, pooled with the first file's seeds),
    ``exploration_noise_bucket_turnlift.json`` (the overhand expert before its lift closed the thumb first, 3 seeds),
    ``exploration_noise_bucket_{arm,hand}.json`` (std 0.3 on one part of the action, seed 0) and
    ``exploration_noise_bucket_hook.json`` (seed 0)."""
    overhand, turned = "experts/exploration_noise_bucket.json", "experts/exploration_noise_bucket_turnlift.json"
    hook, more = "experts/exploration_noise_bucket_hook.json", "experts/exploration_noise_bucket_seeds34.json"
    rows = [[f"overhand ({link(overhand)})", noise_cell(load(overhand), 0.0), noise_cell(load(overhand), 0.1),
             noise_cell(load(overhand), 0.3)],
            [f"overhand, seeds 0-4: the row above and seeds 3-4 ({link(more)})", "",
             bold(noise_cell([load(overhand), load(more)], 0.1)), ""],
            [f"overhand, lift by turning the hand first ({link(turned)})", noise_cell(load(turned), 0.0),
             noise_cell(load(turned), 0.1), noise_cell(load(turned), 0.3)],
            *[[f"overhand, noise on the {what} only, seed 0 ({link(path)})", "", "", noise_cell(load(path), 0.3)]
              for what, path in (("palm twist", "experts/exploration_noise_bucket_arm.json"),
                                 ("hand joint targets", "experts/exploration_noise_bucket_hand.json"))],
            [f"fingertip hook ({link(hook)})", HOOK_NOISELESS, noise_cell(load(hook), 0.1), noise_cell(load(hook), 0.3)],
            ["target", ">= 0.9", ">= 0.8", ">= 0.6"]]
    return table(["bucket expert", "no noise, seen / unseen", "std 0.1", "std 0.3"], rows)


# ---------------------------------------------------------------------------------------------------- students.md

STUDENTS = RES / "students.md"
# (label ("{n}": the seed count), JSON, bold, wall time: None (not a figure: the cores were shared), or the seeds
# whose wall time counts (the others overlapped other work, as the page says), and a note after it)
DISTILLED = [
    ("laptop, defaults", "students/distill_laptop_novel.json", True, (0, 1, 2), ""),
    ("laptop, 2.2x episodes", "students/distill_laptop_episodes2x.json", True, (0, 1, 2), ""),
    ("laptop, 3x episodes", "students/distill_laptop_episodes3x.json", True, (0, 1, 2), ""),
    ("laptop, 2.2x + student noise", "students/distill_laptop_episodes2x_noise.json", True, (0, 1, 2), ""),
    ("laptop, student noise ({n})", "students/distill_laptop_noise.json", False, (0, 1), ""),
    ("laptop, 12 epochs per round ({n})", "students/distill_laptop_epochs12.json", False, (0,), ""),
    ("laptop, velocity and time seen", "students/distill_laptop.json", False, (0, 1, 2), ""),
    ("faucet, defaults", "students/distill_faucet.json", True, (0, 1, 2), ""),
    ("faucet, 2.2x episodes", "students/distill_faucet_episodes2x.json", True, (0, 1, 2), ""),
    ("faucet, 2.2x episodes, successful DAgger episodes only (`successonly`, {n})",
     "rl/curriculum/faucet_cloud_student_successonly.json", False, (0, 1), " (loaded)"),
    ("faucet, velocity and time masked", "students/distill_faucet_novel.json", False, (0, 1, 2), ""),
    ("toilet, defaults", "students/distill_toilet.json", False, (0, 1, 2), ""),
    ("toilet, 2.2x episodes", "students/distill_toilet_episodes2x.json", True, (0, 1, 2), ""),
    ("toilet, 2.2x episodes, successful DAgger episodes only (`successonly`)",
     "rl/curriculum/toilet_cloud_student_successonly.json", True, (0, 1, 2), ""),
    ("toilet, 2.2x + student noise ({n})", "students/distill_toilet_episodes2x_noise.json", False, (1,), ""),
    ("toilet, `successonly` on seen + wide toilets, same episodes (`wide`, {n})",
     "rl/curriculum/toilet_cloud_student_wide.json", False, None, ""),
    ("toilet, `successonly` on seen + wide toilets, 2.2x episodes (`wide2x`, {n})",
     "rl/curriculum/toilet_cloud_student_wide2x.json", False, (0, 1), ""),
    ("bucket, defaults ({n})", "students/distill_bucket.json", False, None, ""),
    ("bucket, demonstration noise 0.05 ({n})", "students/distill_bucket_demonoise005.json", False, None, ""),
    ("bucket, from the overhand expert, lift by turning the hand ({n})", "students/distill_bucket_overhand.json", False,
     None, ""),
    ("bucket, from the overhand expert with the thumb-first lift ({n})", "students/distill_bucket_thumbfirst.json", True,
     None, ""),
]


def frames_cell(seeds: list[dict]) -> str:
    """``expert + student`` frames per seed (the total where the JSON keeps only that)."""
    if "expert_frames" in seeds[0]:
        return f"{kilo([r['expert_frames'] for r in seeds])} + {kilo([r['student_frames'] for r in seeds])}"
    return f"{kilo([r['frames'] for r in seeds])} in all"


def distilled_students() -> str:
    """The DAgger students (``benchmarks/students/bench_distill.py`` and ``curriculum_runs.py --students-only``)."""
    rows = []
    for label, rel, strong, wall_seeds, note in DISTILLED:
        result = load(rel)
        seeds = result["per_seed"]
        n = len(seeds)
        if "{n}" not in label and n != 3:
            raise ValueError(f"{rel}: {n} seeds, but the label does not say so")
        cells = [spread([r[f"{s}_success"] for r in seeds], strong) for s in SPLITS]
        wall = "" if wall_seeds is None else \
            span([r["wall_time_s"] / 60 for r in seeds if r["seed"] in wall_seeds], 1, " min") + note
        files = [link(rel)]
        if (RESULTS / rel).with_suffix(".png").exists():
            files.append(link(str(Path(rel).with_suffix(".png")), "curve"))
        rows.append([label.format(n=f"{n} seeds"), *cells, frames_cell(seeds), wall, ", ".join(files)])
    return table(["DAgger student", "seen", "unseen", "frames / seed (expert + student)", "wall time / seed", "files"], rows)


# Toilet success per template, held out (env seed 1000, 10 deterministic episodes per object, from the true reset;
# benchmarks/students/success_by_template.py): (label, its JSONs, whose runs are pooled)
TOILET_TEMPLATES = [
    ("students (curriculum's)", ["students/success_by_template_toilet_heldout_students.json"]),
    ("students, random occlusion (`erase`)", ["students/success_by_template_toilet_erase_heldout.json"]),
    ("students, tank hidden in half the training episodes (oracle)",
     ["students/success_by_template_toilet_notank_heldout.json"]),
    ("students, successful DAgger episodes only (`successonly`)",
     ["students/success_by_template_toilet_successonly_s0_heldout.json",
      "students/success_by_template_toilet_successonly_s12_heldout.json"]),
    ("students, `successonly` on seen + wide toilets (`wide`)",
     ["students/success_by_template_toilet_wide_heldout.json"]),
    ("students, `wide` with twice the episodes per toilet (`wide2x`)",
     ["students/success_by_template_toilet_wide2x_heldout.json"]),
    ("RL from the curriculum's students (`student_anchored_floor`)", ["rl/success_by_template_toilet_floor_heldout.json"]),
    ("RL, reverse curriculum (`student_anchored_floor_reverse_d17`)",
     ["rl/success_by_template_toilet_reverse_heldout.json"]),
    ("RL from the `wide` students on seen + wide toilets (`student_wide_anchored_floor_reverse_d34_std05`, 818k)",
     ["rl/success_by_template_toilet_wide_rl_heldout.json"]),
]


def template_groups(rels: list[str]) -> tuple[list[str], dict[str, list[float]]]:
    """Per-run success of each group of the toilets' held-out evaluations, pooled over the JSONs ``rels``: seen by
    template, seen, unseen by template, the held-out-band half (unseen objects of the seen templates), unseen. Read
    from the per-object rows (every object has the same episodes there); the templates come from the JSON."""
    results = [load(rel) for rel in rels]
    if {r["eval_file"] for r in results} != {"heldout_{split}_e10_seed1000.json"}:
        raise ValueError(f"{rels}: not all held-out evaluations at env seed 1000")
    per_object = results[0]["per_object"]
    seen_templates = sorted({o["template"] for o in per_object.values() if o["split"] == "seen"})
    unseen_templates = sorted({o["template"] for o in per_object.values() if o["split"] == "unseen"})
    groups = {f"seen {t}": lambda o, t=t: o["split"] == "seen" and o["template"] == t for t in seen_templates}
    groups["seen"] = lambda o: o["split"] == "seen"
    groups.update({f"unseen {t}": lambda o, t=t: o["split"] == "unseen" and o["template"] == t for t in unseen_templates})
    groups["held-out bands"] = lambda o: o["split"] == "unseen" and o["template"] in seen_templates
    groups["unseen"] = lambda o: o["split"] == "unseen"
    values = {}
    for name, member in groups.items():
        values[name] = []
        for result in results:
            objs = [o["per_run"] for o in result["per_object"].values() if member(o)]
            values[name] += [mean([o[r] for o in objs]) for r in range(len(objs[0]))]
    return list(groups), values


def toilet_templates() -> str:
    """Toilet success per template and the unseen split's two halves, held out."""
    rows, header = [], None
    for label, rels in TOILET_TEMPLATES:
        names, values = template_groups(rels)
        header = header or ["policies", "runs", *names, "files"]
        if ["policies", "runs", *names, "files"] != header:
            raise ValueError(f"{rels}: other templates than the rows above")
        files = ", ".join(link(rel, f"JSON {i + 1}" if len(rels) > 1 else "JSON") for i, rel in enumerate(rels))
        rows.append([label, str(len(values["seen"])), *(pm(mean(v), se(v)) for v in values.values()), files])
    return table(header, rows)


# ---------------------------------------------------------------------------------------------------- findings.md

FINDINGS = RES / "findings.md"
STUDIES = "students/studies"


def arm(study: str, name: str) -> dict:
    return load(f"{STUDIES}/{study}/study.json")["arms"][name]


def arm_cell(a: dict, split: str) -> str:
    return pm(a[f"{split}_success"], a[f"{split}_success_std"])


def study_objects() -> str:
    """The objects studies (``laptop_objects``, ``faucet_objects``) and the 2.2x students (``distill_*_episodes2x``)."""
    rows = []
    for label, name in (("5 objects", "seen_half"), ("11 objects", "seen")):
        rows.append([label, *(arm_cell(arm(f"{task}_objects", name), s) for task in ("laptop", "faucet") for s in SPLITS)])
    more = [load(f"students/distill_{task}_episodes2x.json") for task in ("laptop", "faucet")]
    rows.append(["11 objects, 2.2x the budget",
                 *(pm(r[f"{s}_success"], r[f"{s}_success_std"]) for r in more for s in SPLITS)])
    return table(["arm", "laptop seen", "laptop unseen", "faucet seen", "faucet unseen"], rows)


def study_encoder() -> str:
    """The encoder studies (``<task>_encoder``, ``<task>_encoder_sized``)."""
    rows = []
    for study, label in (("laptop_encoder", "laptop"), ("faucet_encoder", "faucet"),
                         ("laptop_encoder_sized", "laptop, sized"), ("faucet_encoder_sized", "faucet, sized")):
        cells = [" / ".join(arm_cell(arm(study, size), s) for s in SPLITS) for size in ("small", "medium", "large")]
        if study == "laptop_encoder":
            cells[2] = bold(cells[2])
        rows.append([f"{label} ({link(f'{STUDIES}/{study}/study.md', 'study')})", *cells])
    return table(["study", "small", "medium", "large"], rows)


PRETRAIN_ARMS = ("scratch", "seg", "cls", "recon", "simsiam")


def study_pretrain() -> str:
    """The ``laptop_pretrain`` study."""
    cells = [" / ".join(arm_cell(arm("laptop_pretrain", a), s) for s in SPLITS) for a in PRETRAIN_ARMS]
    return table(["encoder", "scratch", "seg", "cls", "recon", "SimSiam"], [["laptop, seen / unseen", *cells]])


VIEW_GRID = {"azimuths_deg": [-60, -40, -20, 0, 20, 40, 60], "polars_deg": [-20, -10, 0, 10, 20]}


def viewpoint_cells(a: dict) -> list[str]:
    """At the training camera, then over the 35-camera grid (``viewpoint_success[split][polar][azimuth]``): its
    mean, the centre cell, and the range of the mean success of the ±20° and ±60° azimuth columns over both splits."""
    grid = a["viewpoint_success"]
    azimuths, polars = VIEW_GRID["azimuths_deg"], VIEW_GRID["polars_deg"]
    centre = [grid[s][polars.index(0)][azimuths.index(0)] for s in SPLITS]

    def columns(deg: int) -> str:
        means = [mean([row[azimuths.index(az)] for row in grid[s]]) for s in SPLITS for az in (-deg, deg)]
        return span(means, 2)

    return [" / ".join(arm_cell(a, s) for s in SPLITS), " / ".join(f2(a["viewpoint_mean"][s]) for s in SPLITS),
            " / ".join(f2(c) for c in centre), columns(20), columns(60)]


def study_viewpoint() -> str:
    """The ``laptop_viewpoint`` and ``laptop_viewpoint-2d`` studies."""
    rows = []
    for study, name, label in (("laptop_viewpoint", "fixed", "point cloud, fixed training camera"),
                               ("laptop_viewpoint", "random", "point cloud, random viewpoint at every reset (`random`)"),
                               ("laptop_viewpoint-2d", "depth_cnn", "depth image, small CNN"),
                               ("laptop_viewpoint-2d", "depth_cnn_shift",
                                "depth image, random shifts up to 4 px (`depth_cnn_shift`)")):
        grid = load(f"{STUDIES}/{study}/study.json")["viewpoint_grid"]
        if {k: grid[k] for k in VIEW_GRID} != VIEW_GRID:
            raise ValueError(f"{study}: another camera grid than {VIEW_GRID}")
        rows.append([label, *viewpoint_cells(arm(study, name))])
    return table(["student", "at the training camera", "grid mean", "centre cell", "±20° azimuth columns",
                  "±60° azimuth columns"], rows)


# ---------------------------------------------------------------------------------------------------- performance.md

PERFORMANCE = RES / "performance.md"
# (row, the pieces of bench_sim.json's ``breakdown`` it sums)
STEP_PIECES = [
    ("10 physics sub-steps (`stepSimulation`)", ("physics_substeps",)),
    ("depth + segmentation render (TinyRenderer, 64 x 64)", ("render",)),
    ("state read (robot, object, contact filtering; the contact query itself {contacts})", ("state_read", "contacts")),
    ("point-cloud assembly (crop, sampling, noise), back-projection, labels", ("cloud_assembly", "back_project", "labels")),
    ("96 imagined points (forward kinematics)", ("imagine",)),
    ("arm IK (twist -> joint velocities)", ("arm_ik",)),
    ("arm motor targets, 10 per step", ("arm_motors_per_substep",)),
    ("reward terms and info, state vector, hand motors, action check, the step's own lines",
     ("reward_and_info", "state_vector", "hand_motors", "check_action", "step_glue")),
    ("gymnasium's wrappers (wrapped minus bare step)", ("wrappers",)),
]


def step_breakdown() -> str:
    """``bench_sim.json``'s ``breakdown``: ms per control step of each piece and its share of their sum."""
    ms = load("perf/bench_sim.json")["breakdown"]["ms_per_step"]
    if sorted(k for _, keys in STEP_PIECES for k in keys) != sorted(ms):
        raise ValueError("bench_sim.json's breakdown has other pieces than STEP_PIECES")
    total = sum(ms.values())
    rows = []
    for label, keys in STEP_PIECES:
        value = sum(ms[k] for k in keys)
        cell = "~0" if abs(value) < 0.01 else f"{value:.2f}"
        rows.append([label.format(contacts=f"{ms['contacts']:.3f}"), cell, f"{max(0.0, 100 * value / total):.0f} %"])
    return table(["piece of `env.step` (Laptop)", "ms per control step", "share"], rows)


def env_throughput() -> str:
    """``bench_envs.json``: random actions, 2,000 resets."""
    tasks = load("perf/bench_envs.json")["tasks"]
    rows = [[t, f"{tasks[t]['steps_per_s']:.0f}", f"{tasks[t]['steps_per_s_2proc']:.0f}", f2(tasks[t]["vs_physics_only"])]
            for t in TASKS]
    return table(["task", "env steps/s, 1 process", "2 processes (total)", "full step / physics-only step"], rows)


PHYSICS = ("50x10", "30x10", "20x10", "50x5", "20x5")


def physics_solvers() -> str:
    """``bench_physics_solvers.json``: the scripted solvers' success per physics setting."""
    result = load("perf/bench_physics_solvers.json")
    solvers = result["solvers"]
    header = ["scripted solver success, seen / unseen",
              *(f"{p} (the defaults)" if p == result["baseline"] else p for p in PHYSICS)]
    rows = [[t, *(" / ".join(f2(solvers[t][s][p]["success_rate"]) for s in SPLITS) for p in PHYSICS)] for t in TASKS]
    return table(header, rows)


def physics_speed() -> str:
    """``bench_physics_speed.json``: env steps/s per physics setting (x the baseline's)."""
    result = load("perf/bench_physics_speed.json")
    rows = []
    for t in TASKS:
        speed = result["speed"][t]
        cells = [f"{speed[p]['steps_per_s']:.0f}" + ("" if p == result["baseline"] else f" (x{speed[p]['vs_baseline']:.2f})")
                 for p in PHYSICS]
        rows.append([t, *cells])
    return table(["env steps/s, 1 process (x the defaults)", *PHYSICS], rows)


TRAINING_RUNS = ("perf/bench_training.json", "perf/bench_training_run2.json")  # two runs of the command on one VM
COLLECTION = [
    ("plain `obs -> policy -> env.step` loop, 1 process", "single_loop"),
    ("the same loop in 2 processes (total)", "parallel_loop"),
    ("torchrl `Collector`, in process", "collector_1"),
    ("torchrl `MultiSyncCollector`, 2 workers, 4,000-frame batches (what `train` uses on the `cpu` preset)", "collector_2"),
    ("the same, 1,000-frame batches", "collector_2_batch1000"),
]


def collection() -> str:
    """``bench_training.json`` and ``bench_training_run2.json``'s ``collection_fps``."""
    runs = [load(rel)["collection_fps"] for rel in TRAINING_RUNS]
    rows = [[label, *(f"{run[key]:.0f}" for run in runs)] for label, key in COLLECTION]
    return table(["collection, Laptop, small-PointNet policy choosing every action", "frames/s, run 1", "run 2"], rows)


def encoder_update() -> str:
    """``bench_training.json`` (run 1)'s ``update``: a PPO minibatch and a faithful update per encoder size."""
    update = load(TRAINING_RUNS[0])["update"]
    rows = [[size, f"{update[size]['minibatch_s']:.2f} s", f"{update[size]['faithful_update_s']:.0f} s"]
            for size in ("small", "medium", "large")]
    return table(["encoder", "one PPO minibatch of 500 (fwd + bwd + Adam)", "one faithful update (20k frames x 10 epochs)"],
                 rows)


ITERATION_RUNS = ("perf/bench_training_vs_2f696c9.json", "perf/bench_training_amd_nov27.json")  # each alone on its VM


def cpu_iteration() -> str:
    """A whole ``cpu``-preset iteration (``iteration`` of each JSON) and the faithful preset's estimate."""
    rows = []
    for rel in ITERATION_RUNS:
        result = load(rel)
        it = result["iteration"]
        faithful = it["faithful_estimate"]
        rows.append([f"{machine_name(result)}, alone ({link(rel)})",
                     *(f"{it[k]:.0f}" for k in ("iteration_fps", "collect_fps", "update_fps")),
                     f"{faithful['iteration_fps']:.0f} frames/s ({faithful['hours_per_1M_frames']:.1f} h per 1M frames)"])
    return table(["machine", "iteration, frames/s", "collection", "update", "faithful preset"], rows)


def physics_iteration() -> str:
    """``bench_training_physics_20x5.json``: the iteration with the default physics and with 20x5, side by side."""
    result = load("perf/bench_training_physics_20x5.json")["iteration_vs_physics"]
    base, cheap = result["default"], result["with_setting"]
    if result["setting"] != "20x5":
        raise ValueError("the row's label describes 20x5")
    rows = [["physics 50x10 (the defaults)", *(f"{base[k]:.0f}" for k in ("collect_fps", "update_fps", "iteration_fps"))],
            ["physics 20x5 (20 solver iterations, 5 sub-steps of 8 ms)",
             f"{cheap['collect_fps']:.0f} (x{cheap['collect_fps'] / base['collect_fps']:.2f})", f"{cheap['update_fps']:.0f}",
             f"{cheap['iteration_fps']:.0f} (**x{result['iteration_vs_default']:.2f}**)"]]
    return table([f"cpu-preset iteration, Laptop (medians of {result['rounds']})", "collect", "update", "whole iteration"],
                 rows)


def ppo_encoder_size() -> str:
    """``benchmarks/results/rl/learning_laptop_encoder_<size>.json`` (``bench_learning.py``, seed 0, 32k frames)."""
    rows = []
    for size in ("small", "medium", "large"):
        r = load(f"rl/learning_laptop_encoder_{size}.json")
        rows.append([size, f"{r['frames']:,}", f"{r['wall_time_s'] / 60:.1f} min", f"{r['collect_fps']:.0f}",
                     f"{r['update_fps']:.0f}", f"{f2(r['seen_success'])} / {f2(r['unseen_success'])}"])
    return table(["encoder", "frames", "training wall time", "collection frames/s", "update frames/s",
                  "seen / unseen success"], rows)


# ---------------------------------------------------------------------------------------------------- ppo.md

PPO = RES / "ppo.md"
BLOCK = 60_000  # "collected success per 60k frames": the mean success of the collected episodes over 15 batches


def blocks(history: list[dict], key: str = "success_rate") -> list[float]:
    """The mean of ``key`` over each 60k frames of a run's per-batch history."""
    out: dict[int, list[float]] = {}
    for row in history:
        out.setdefault((row["frames"] - 1) // BLOCK, []).append(row[key])
    return [mean(v) for _, v in sorted(out.items())]


def finetune_collapse() -> str:
    """``finetune_laptop_collapse.json``, ``finetune_laptop_klstop.json``, ``finetune_laptop_klstop_bc.json``
    (``benchmarks/rl/bench_finetune.py``, laptop student seed 0): the collected episodes' success over the critic's
    warm-up batches, then over the last 60k frames."""
    rows = []
    for label, rel, curve in (
            ("std 0.2, lr 3e-5, 3 warm-up batches (the first `finetune` preset; {json})",
             "rl/finetune_laptop_collapse.json", False),
            ("+ the `finetune` preset's guards (above; {json}, {curve})", "rl/finetune_laptop_klstop.json", True),
            ("the same + a constant BC term towards the expert labels of the demonstrations (DAPG-style; {json})",
             "rl/finetune_laptop_klstop_bc.json", False)):
        result = load(rel)
        (run,) = result["per_seed"]
        history = run["history"]
        warm = [r["success_rate"] for r in history if r.get("critic_warmup")]
        last = [r["success_rate"] for r in history if r["frames"] > history[-1]["frames"] - BLOCK]
        text = label.format(json=link(rel), curve=link(rel.replace(".json", ".png"), "curve") if curve else "")
        rows.append([text, f"{run['frames'] / 1000:.0f}k", f"{f2(run['seen_success'])} / {f2(run['unseen_success'])}",
                     f"{f2(mean(warm))} -> {f2(mean(last))}", f"{run['wall_time_s'] / 60:.1f} min"])
    return table(["PPO from the student", "frames", "seen / unseen at the end",
                  "success of the collected episodes (warm-up batches -> last 60k frames)", "wall time"], rows)


def pair(a: float, b: float) -> str:
    return f"{f2(a)} / {f2(b)}"


def finetune_rows(label: str, rel: str, strong_mean: bool = False) -> list[list[str]]:
    """A fine-tune JSON's rows: each seed, then the mean over the seeds: the student and the final policy in their
    own evaluation (3 episodes per object) and held out, the collected success per 60k frames, the wall time."""
    result = load(rel)
    held = {r["seed"]: r for r in result["heldout"]["per_seed"]}
    rows = []
    for run in result["per_seed"]:
        h = held[run["seed"]]
        rows.append([label.format(seed=f"seed {run['seed']}"), pair(run["student_seen"], run["student_unseen"]),
                     pair(run["seen_success"], run["unseen_success"]), pair(h["student_seen"], h["student_unseen"]),
                     pair(h["seen_success"], h["unseen_success"]), ", ".join(f2(b) for b in blocks(run["history"])),
                     f"{run['wall_time_s'] / 60:.1f} min"])
    if len(result["per_seed"]) > 1:
        h = result["heldout"]
        rows.append([label.format(seed="mean"), pair(result["student_seen"], result["student_unseen"]),
                     pair(result["seen_success"], result["unseen_success"]), pair(h["student_seen"], h["student_unseen"]),
                     bold(pair(h["seen_success"], h["unseen_success"]), strong_mean), "", ""])
    return rows


FINETUNE_HEADER = ["student, 3 per object", "after PPO, 3 per object", "student, held out", "after PPO, held out",
                   "collected success per 60k frames", "wall time"]


def finetune_laptop() -> str:
    """``finetune_laptop_anchor.json`` and ``finetune_laptop_noanchor.json``."""
    rows = [*finetune_rows("anchor 1, {seed}", "rl/finetune_laptop_anchor.json", strong_mean=True),
            *finetune_rows("no anchor, {seed}", "rl/finetune_laptop_noanchor.json")]
    return table(["Laptop, 300k PPO frames", *FINETUNE_HEADER], rows)


def finetune_faucet() -> str:
    """The ``finetune_faucet*.json`` runs (* : students distilled anew with the same command)."""
    rows = [*finetune_rows("`finetune`, {seed}", "rl/finetune_faucet.json", strong_mean=True),
            *finetune_rows("anchor 1, {seed}", "rl/finetune_faucet_anchor.json"),
            *finetune_rows("anchor 0.3, {seed}", "rl/finetune_faucet_anchor03.json"),
            *finetune_rows("frozen PointNet*, {seed}", "rl/finetune_faucet_frozen.json"),
            *finetune_rows("self-imitation*, {seed}", "rl/finetune_faucet_sil.json"),
            *finetune_rows("`finetune`*, {seed} (control)", "rl/finetune_faucet_redistilled.json"),
            *finetune_rows("looser KL stop*, {seed}", "rl/finetune_faucet_kl03.json", strong_mean=True)]
    return table(["Faucet, 300k PPO frames", *FINETUNE_HEADER], rows)


# DexArt's Table 2 laptop row (no pretraining, ~15M frames on a GPU cluster): quoted from the paper
PAPER_ROW = ["DexArt paper, Table 2, no pretraining", "~15M", "GPU cluster", f2(PAPER_NO_PRETRAIN["laptop"][0]),
             f2(PAPER_NO_PRETRAIN["laptop"][1]), ""]


def rate(evaluation: dict) -> str:
    """``0.00 (0/44)``: a success rate with its successes and episodes."""
    n = evaluation["episodes"]
    return f"{f2(evaluation['success_rate'])} ({round(evaluation['success_rate'] * n)}/{n})"


def ppo_scratch() -> str:
    """``learning_laptop.json`` (``bench_learning.py``, the ``cpu`` preset, 1M frames) beside DexArt's Table 2."""
    r = load("rl/learning_laptop.json")
    row = [f"dexart_lite, `{r['preset']}` preset, {r['config']['encoder']} PointNet, seed {r['config']['seed']}",
           f"{r['frames']:,}", f"{r['wall_time_s'] / 60:.0f} min", rate(r["seen"]), rate(r["unseen"]),
           f"{f2(r['seen_mean_max_stage'])} / {f2(r['unseen_mean_max_stage'])}"]
    return table(["run", "frames", "training wall time", "seen success", "unseen success",
                  "mean stage reached (seen / unseen)"], [row, PAPER_ROW])


def phased_noise() -> str:
    """``exploration_noise_laptop_phased.json``: the first (phase-machine) laptop expert under action noise."""
    rows = []
    for r in load("experts/exploration_noise_laptop_phased.json")["rows"]:
        sigma = f"{r['action_noise']:.1f}"
        if r["action_noise"] == 1:
            sigma += " (PPO's start, DexArt's initial `log_std` 0)"
        fractions = " / ".join(f2(r["stage_fractions"][f"stage{k}"]) for k in (1, 2, 3))
        rows.append([sigma, f2(r["success_rate"]), f2(r["mean_max_stage"]), fractions, f"{r['mean_return']:.1f}"])
    return table(["action noise std", "success", "mean highest stage", "steps in stage 1 / 2 / 3", "mean return"], rows)


def percent_span(values) -> str:
    """``32-46 %`` of fractions."""
    return span([100 * v for v in values], 0, " %")


def training_return(points: list[dict], upto: int) -> str:
    """The training return over the first and the last 40k frames of the run's first ``upto`` frames."""
    points = [p for p in points if p["frames"] <= upto]
    first = [p["episode_return"] for p in points if p["frames"] <= 40_000]
    last = [p["episode_return"] for p in points if p["frames"] > upto - 40_000]
    return f"{mean(first):.1f} -> {mean(last):.1f}"


# The std-1.0 row's other columns come from a 200k-frame run of the same seed whose JSON was not kept (the committed
# learning_laptop.json is the 1M-frame run); its training return is the 1M run's first 200k frames
DEFAULT_NOISE_200K = ["~5 %", "1 batch of 50 above zero (0.03 %)", "-10.1 / -10.3", "1.25 / 1.33", "0"]


def init_log_std() -> str:
    """``learning_laptop.json`` (its first 200k frames) and ``learning_laptop_init_log_std_-1.2.json``."""
    default, low = load("rl/learning_laptop.json"), load("rl/learning_laptop_init_log_std_-1.2.json")
    stage3 = sum(p["stage3_frac"] > 0 for p in low["curve_points"])
    rows = [["initial std 1.0 (DexArt)", training_return(default["curve_points"], 200_000), *DEFAULT_NOISE_200K],
            ["initial std 0.3", training_return(low["curve_points"], low["frames"]),
             percent_span([b["stage2_frac"] for b in low["last_batches"]]), str(stage3),
             f"{low['seen']['mean_return']:.1f} / {low['unseen']['mean_return']:.1f}",
             pair(low["seen_mean_max_stage"], low["unseen_mean_max_stage"]),
             "0" if low["seen_success"] == low["unseen_success"] == 0 else pair(low["seen_success"], low["unseen_success"])]]
    return table(["first 200k frames, seed 0", "training return, first -> last 40k frames",
                  "steps in contact (stage 2), last batches", "steps in stage 3", "eval return seen / unseen",
                  "eval stage seen / unseen", "success"], rows)


def stage3_batches(runs: list[dict]) -> str:
    """How many batches of the runs had a stage-3 step, and the largest share of a batch's steps in stage 3."""
    hits = [p["stage3_frac"] for r in runs for p in r["curve_points"] if p["stage3_frac"] > 0]
    if not hits:
        return "none in any batch"
    if len(hits) == 1:
        return f"one batch ({100 * hits[0]:.1f} %)"
    return f"{len(hits)} batches (at most {100 * max(hits):.1f} %)"


def state_shaped() -> str:
    """``learning_laptop_state_{shaped,dexart}_s{0,1}.json``: the laptop on the state, 300k frames, 2 seeds."""
    rows = []
    for tag, label in (("shaped", "shaped reward"), ("dexart", "DexArt's reward")):
        rels = [f"rl/learning_laptop_state_{tag}_s{k}.json" for k in (0, 1)]
        runs = [load(rel) for rel in rels]
        links = ", ".join(link(rel, f"s{k}") for k, rel in enumerate(rels))
        success = " / ".join(f2(mean([r[f"{s}_success"] for r in runs])) for s in SPLITS)
        rows.append([f"{label} ({links})", success, " / ".join(f2(r["seen_mean_max_stage"]) for r in runs),
                     percent_span([b["stage2_frac"] for r in runs for b in r["last_batches"]]), stage3_batches(runs)])
    return table(["laptop, state only, 300k frames", "success", "mean highest stage (seed 0 / 1)",
                  "steps in stage 2, last batches", "stage-3 steps"], rows)


def kframes(values: list) -> str:
    """``24k, 4k frames`` per seed (``none`` where no seed got there)."""
    if all(v is None for v in values):
        return "none"
    return ", ".join("none" if v is None else f"{v / 1000:.0f}k" for v in values) + " frames"


def stages(runs: list[dict]) -> str:
    return span([r[f"{s}_mean_max_stage"] for r in runs for s in SPLITS], 2)


def state_diagnostic() -> str:
    """``state_diagnostic.json`` (``benchmarks/rl/state_diagnostic.py``, DexArt's reward, 2 seeds x 300k frames)."""
    result = load("rl/state_diagnostic.json")
    rows = []
    for task in ("faucet", "laptop", "toilet", "bucket"):
        runs = result["tasks"][task]["per_seed"]
        stage3 = [r["frames_to_first_stage3"] for r in runs]
        rows.append([task, kframes([r["frames_to_first_success"] for r in runs]),
                     kframes(stage3).replace(" frames", ""),
                     ", ".join(f2(r["best_batch_success"]) if r["best_batch_success"] else "0" for r in runs),
                     pair(result["tasks"][task]["seen_success"], result["tasks"][task]["unseen_success"]), stages(runs),
                     ", ".join(f"{r['wall_time_s'] / 60:.1f}" for r in runs) + " min"])
    return table(["task, state only, 300k frames", "first collected success (seed 0, 1)", "first stage-3 step",
                  "best batch's success", "deterministic success seen / unseen", "mean stage", "wall time"], rows)


# (row, the state_diagnostic JSON, task, the learning JSONs' tag (their per-batch stage-3 share))
FAST_ROWS = [
    ("faucet, `fast`", "rl/state_diagnostic_fast.json", "faucet", "fast"),
    ("faucet, `fast` + self-imitation", "rl/state_diagnostic_fast_sil_faucet.json", "faucet", "fast_sil"),
    ("faucet, `fast` + 3 synergies", "rl/state_diagnostic_fast_synergy_faucet.json", "faucet", "fast_synergy"),
    ("laptop, `fast`", "rl/state_diagnostic_fast.json", "laptop", "fast"),
    ("laptop, `fast` + self-imitation", "rl/state_diagnostic_fast_sil_laptop.json", "laptop", "fast_sil"),
    ("laptop, `fast` + 3 synergies", "rl/state_diagnostic_fast_synergy_laptop.json", "laptop", "fast_synergy"),
]


def deterministic(runs: list[dict], learning: list[dict]) -> str:
    """Each seed's ``seen / unseen`` deterministic success, with ``(k of n)`` where it is not zero."""
    cells = []
    for r, l in zip(runs, learning):
        parts = []
        for s in SPLITS:
            n = l[s]["episodes"]
            value = r[f"{s}_success"]
            parts.append(f2(value) + (f" ({round(value * n)} of {n})" if value else ""))
        cells.append(" / ".join(parts))
    if len(set(cells)) > 1:
        return ", ".join(cells)
    return cells[0] + (", both seeds" if "(" in cells[0] else " (both seeds)")


def stage3_share(learning: list[dict]) -> str:
    """Each seed's share of steps in stage 3, the mean over its batches."""
    shares = [100 * mean([p["stage3_frac"] for p in l["curve_points"]]) for l in learning]
    if not any(shares):
        return "0, 0"
    return ", ".join("0" if v == 0 else "< 0.01 %" if v < 0.005 else f"{v:.2f} %" for v in shares)


def state_fast() -> str:
    """The ``state_diagnostic_fast*.json`` runs and their ``learning_<task>_state_<tag>_s<seed>.json``."""
    rows = []
    for label, rel, task, tag in FAST_ROWS:
        runs = load(rel)["tasks"][task]["per_seed"]
        learning = [load(f"rl/learning_{task}_state_{tag}_s{r['seed']}.json") for r in runs]
        rows.append([label, kframes([r["frames_to_first_success"] for r in runs]),
                     ", ".join(f2(r["best_batch_success"]) if r["best_batch_success"] else "0" for r in runs),
                     stage3_share(learning), deterministic(runs, learning), stages(runs),
                     ", ".join(f"{r['wall_time_s'] / 60:.1f}" for r in runs) + " min"])
    return table(["state only, 300k frames", "first collected success (seed 0, 1)", "best batch's success",
                  "steps in stage 3 (mean over batches)", "deterministic success seen / unseen", "mean stage", "wall time"],
                 rows)


def synergy_expert() -> str:
    """``synergy_expert.json``: the experts with all 16 hand joints and projected on 3 synergies, the same episodes."""
    rows = load("experts/synergy_expert.json")["rows"]
    cell = {(r["task"], r["split"]): r for r in rows}
    full = [" / ".join(f2(cell[t, s]["full_hand_success"]) for s in SPLITS) for t in TASKS]
    synergy = [" / ".join(f2(cell[t, s]["synergy_success"]) for s in SPLITS) for t in TASKS]
    return table(["expert, success seen / unseen", *TASKS], [["16 hand joints (`solve_*.json`)", *full],
                                                            ["projected on 3 synergies", *synergy]])


# (row, state_diagnostic JSON): the faucet runs on the state
FAUCET_CURVES = [
    ("DexArt's reward, the departures above", "rl/state_diagnostic.json"),
    ("`fast`", "rl/state_diagnostic_fast.json"),
    ("`fast` + self-imitation", "rl/state_diagnostic_fast_sil_faucet.json"),
    ("`fast` + 3 synergies", "rl/state_diagnostic_fast_synergy_faucet.json"),
]


def faucet_collected() -> str:
    """The faucet's collected success per 60k frames (each state-diagnostic run's per-batch ``curve``)."""
    rows = []
    for label, rel in FAUCET_CURVES:
        runs = load(rel)["tasks"]["faucet"]["per_seed"]
        curves = [[{"frames": f, "success_rate": v} for f, v in r["curve"]] for r in runs]
        rows.append([label, *(", ".join(f"{b:.3f}" for b in blocks(curve)) for curve in curves)])
    return table(["faucet, state only", "seed 0", "seed 1"], rows)


# ---------------------------------------------------------------------------------------------------- students.md: make demo

# `time make demo` on each machine (the venv installed, nothing else running): measured with the shell's `time`,
# which no JSON records
DEMO_WALL = {"demo": "7 min 31 s", "demo_amd_nov27": "8 min 3 s"}


def demo_frames(folder: str) -> str:
    """``expert + student`` frames from the run's report (written by ``make demo`` beside its JSON)."""
    text = (RESULTS / "students" / folder / "report.md").read_text()
    found = re.search(r"expert frames ([\d,]+) .*?student frames ([\d,]+)", text)
    if found is None:
        raise ValueError(f"{folder}/report.md names no expert and student frames")
    return f"{found.group(1)} + {found.group(2)}"


def make_demo() -> str:
    """``benchmarks/results/students/demo*/eval_{seen,unseen}.json`` (``make demo`` on two 2-core machines)."""
    rows = []
    for machine, folder in (("A", "demo"), ("B", "demo_amd_nov27")):
        ev = {s: load(f"students/{folder}/eval_{s}.json") for s in SPLITS}
        if machine == "A":
            cells = [f"**{f2(ev['seen']['success_rate'])}** (mean stage {f2(ev['seen']['mean_max_stage'])})",
                     f"**{f2(ev['unseen']['success_rate'])}** ({f2(ev['unseen']['mean_max_stage'])})"]
            files = [link(f"students/{folder}/report.md", "report"), link(f"students/{folder}/rounds.png", "curve"),
                     link("students/demo_laptop_unseen_episode.gif", "GIF")]
        else:
            cells = [f"**{f2(ev[s]['success_rate'])}** ({f2(ev[s]['mean_max_stage'])})" for s in SPLITS]
            files = [link(f"students/{folder}/report.md", "report"), link(f"students/{folder}/eval_seen.json", "seen"),
                     link(f"students/{folder}/eval_unseen.json", "unseen")]
        rows.append([f"2-core machine {machine}", DEMO_WALL[folder], demo_frames(folder), *cells, ", ".join(files)])
    return table(["machine", "wall time", "frames (expert + student)", "seen", "unseen", "files"], rows)


# ---------------------------------------------------------------------------------------------------- pretraining.md

PRETRAINING = RES / "pretraining.md"


def pretraining() -> str:
    """``seg_miou.json``, ``methods.json`` and ``ppo_laptop_pretrained_vs_scratch.json`` (benchmarks/results/pretraining),
    beside DexArt's Table 2."""
    seg = load("pretraining/seg_miou.json")
    methods = load("pretraining/methods.json")["runs"]
    ppo = load("pretraining/ppo_laptop_pretrained_vs_scratch.json")
    rows = []
    for task in TASKS:
        t = seg["tasks"][task]
        label = (f"segmentation mIoU (4 classes, {t['epochs']} epochs, {seg['samples_per_object']:,} clouds per object): "
                 f"{task}") if task == TASKS[0] else task
        rows.append([label, f2(t["miou_seen"]), f2(t["miou_unseen"])])
    cls, recon = methods["cls_objects"], methods["recon_laptop"]
    rows.append([f"classification of the 4 categories, objects-only set (accuracy)", f2(cls["val"]["accuracy"]),
                 f2(cls["test"]["accuracy"])])
    rows.append(["reconstruction, Laptop DAM (Chamfer)", f"{recon['val']['chamfer_mm']:.1f} mm",
                 f"{recon['test']['chamfer_mm']:.1f} mm"])
    arms = ppo["arms"]
    rows.append([f"Laptop PPO success after {ppo['frames'] / 1000:.0f}k frames, scratch / seg-pretrained "
                 f"(seed {', '.join(map(str, ppo['seeds']))})",
                 *(f"{f2(arms['scratch'][f'success_{s}'])} / {f2(arms['pretrained'][f'success_{s}'])}" for s in SPLITS)])
    rows.append(["DexArt paper, Laptop, scratch / seg-pretrained (~15M frames)",
                 *(f"{f2(PAPER_NO_PRETRAIN['laptop'][k])} / {f2(PAPER_LAPTOP_SEG[k])}" for k in (0, 1))])
    return table(["", "seen", "unseen"], rows)


# ---------------------------------------------------------------------------------------------------- rl_from_experts.md

RL_FROM_EXPERTS = RES / "rl_from_experts.md"
# what limits each task's headline run set (a link into the page), by (task, observation); which run set it is, is
# the headline rule's choice (curriculum_table.headline), not written here
LIMITS = {("laptop", "state"): "[the clone](#what-ppo-must-start-from)",
          ("faucet", "state"): "[the clone, the bonus](#rewards-dexarts-bonus-pays-for-speed)",
          ("laptop", "cloud"): "[a slow climb](#laptop)", ("faucet", "cloud"): "[unseen faucets](#faucet)",
          ("toilet", "cloud"): "[students, template C](#toilet)", ("bucket", "cloud"): "[a run still going: 1536k of 2M](#bucket)"}
RECIPE_NOTES = {"dagger8_wide_flat": " (flat bonus)"}


def recipes() -> str:
    """Each task's run set: on the state its own evaluation (``rl/curriculum/<task>_state_<recipe>.json``; from its
    DAgger clones' success, the BC warm start's), on point clouds the held-out re-evaluation beside its students
    (``rl/paired_eval.json``)."""
    paired = {(e["task"], e["recipe"]): e for e in load("rl/paired_eval.json")["summary"]}
    headline = curriculum_module().headline
    chosen = []
    for obs, column in (("state", "rl_state"), ("cloud", "rl")):
        for task in ("laptop", "faucet", "toilet", "bucket"):
            pick = headline(task)[column]
            if pick is not None:
                recipe = pick["entry"]["recipe"] if obs == "cloud" else Path(pick["name"]).stem[len(f"{task}_state_"):]
                chosen.append((task, obs, recipe, LIMITS[task, obs]))
    rows = []
    for task, obs, recipe, limit in chosen:
        if obs == "state":
            result = load(f"rl/curriculum/{task}_state_{recipe}.json")
            seeds = result["per_seed"]
            values = f"{pair(result['seen_success'], result['unseen_success'])} (own)"
            start = "clones " + " / ".join(f2(mean([r["warmstart_success"][s] for r in seeds])) for s in SPLITS)
            frames = [r["frames"] for r in seeds]
            label = f"{task}, state"
        else:
            e = paired[task, recipe]
            values = pair(e["seen"]["rl"], e["unseen"]["rl"])
            start = f"students {pair(e['seen']['student'], e['unseen']['student'])}"
            frames = e["rl_frames"]
            label = f"{task}, clouds"
        rows.append([label, f"`{recipe}`{RECIPE_NOTES.get(recipe, '')}", values, start,
                     " / ".join(f"{f / 1000:.0f}k" for f in frames), limit])
    return table(["task, observation", "recipe (`curriculum_runs.py --recipe`)", "seen / unseen", "from", "frames / seed",
                  "limited by"], rows)


def bucket_from_h() -> str:
    """``bucket_expert_noise{,_arm,_hand}_from_h.json`` (``benchmarks/rl/success_from_h.py --policy expert``): the
    bucket expert taking over its own episode after h steps, with action noise."""
    every = load("rl/bucket_expert_noise_from_h.json")
    arm_only, hand_only = load("rl/bucket_expert_noise_arm_from_h.json"), load("rl/bucket_expert_noise_hand_from_h.json")
    hs = every["h"]

    def row(result: dict, policy: str) -> list[str]:
        return [f2(result["policies"][policy]["by_h"][str(h)]["success"]) for h in hs]

    rows = [["0.03, all 22 dimensions", *row(every, "expert+noise0.03")], ["0.05, all", *row(every, "expert+noise0.05")],
            ["0.1, all", *row(every, "expert+noise0.1")],
            ["0.1 on the palm twist only / the hand's targets only",
             *(f"{a} / {b}" for a, b in zip(row(arm_only, "expert+noise0.1@arm"), row(hand_only, "expert+noise0.1@hand")))]]
    return table(["noise std after the hand-over", *(f"h = {h}" if h == hs[0] else str(h) for h in hs)], rows)


TABLES = {
    "expert-success": (EXPERTS, expert_success), "expert-noise": (EXPERTS, expert_noise),
    "bucket-expert-noise": (EXPERTS, bucket_expert_noise),
    "distilled-students": (STUDENTS, distilled_students), "make-demo": (STUDENTS, make_demo),
    "toilet-templates": (STUDENTS, toilet_templates),
    "study-objects": (FINDINGS, study_objects), "study-encoder": (FINDINGS, study_encoder),
    "study-pretrain": (FINDINGS, study_pretrain), "study-viewpoint": (FINDINGS, study_viewpoint),
    "step-breakdown": (PERFORMANCE, step_breakdown), "env-throughput": (PERFORMANCE, env_throughput),
    "physics-solvers": (PERFORMANCE, physics_solvers), "physics-speed": (PERFORMANCE, physics_speed),
    "collection": (PERFORMANCE, collection), "encoder-update": (PERFORMANCE, encoder_update),
    "cpu-iteration": (PERFORMANCE, cpu_iteration), "physics-iteration": (PERFORMANCE, physics_iteration),
    "ppo-encoder-size": (PERFORMANCE, ppo_encoder_size),
    "finetune-collapse": (PPO, finetune_collapse), "finetune-laptop": (PPO, finetune_laptop),
    "finetune-faucet": (PPO, finetune_faucet), "ppo-scratch": (PPO, ppo_scratch), "phased-noise": (PPO, phased_noise),
    "init-log-std": (PPO, init_log_std), "state-shaped": (PPO, state_shaped), "state-diagnostic": (PPO, state_diagnostic),
    "state-fast": (PPO, state_fast), "synergy-expert": (PPO, synergy_expert), "faucet-collected": (PPO, faucet_collected),
    "pretraining": (PRETRAINING, pretraining),
    "recipes": (RL_FROM_EXPERTS, recipes), "bucket-from-h": (RL_FROM_EXPERTS, bucket_from_h),
}


# The tables in docs/ that stay typed, by their header line: none of them is a result with a JSON behind it
TYPED = {
    "| task | goal | seen / unseen objects | success (any step of the episode) |":
        "docs/benchmark.md: the tasks' definitions (goal, object counts, success thresholds), not results",
    "| | DexArt (`*_thick_handle` assets) | dexart_lite | why |":
        "docs/results/experts.md: the bail's physics settings against DexArt's, not results",
    "| finding (paper) | verdict here |":
        "docs/results/findings.md: the verdicts in words; their figures are in the generated tables below it",
}


# ---------------------------------------------------------------------------------------------------- the command


def curriculum_module():
    """``benchmarks/rl/curriculum_table.py``, loaded as ``tests/test_docs_tables.py`` loads it."""
    spec = importlib.util.spec_from_file_location("curriculum_table", CURRICULUM_TABLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules["curriculum_table"] = module  # where @dataclass looks a module up
    spec.loader.exec_module(module)
    return module


def curriculum_tables() -> dict:
    """``curriculum_table.py``'s ``TABLES`` (RL from the experts, the README's headline and zoo, the scaling table)."""
    return curriculum_module().TABLES


def all_tables() -> dict:
    """Every generated table in the repository: name -> (file, function)."""
    curriculum = curriculum_tables()
    if set(curriculum) & set(TABLES):
        raise ValueError(f"tables named twice: {sorted(set(curriculum) & set(TABLES))}")
    return {**TABLES, **curriculum}


def block(text: str, name: str) -> re.Match | None:
    return re.search(rf"<!-- {re.escape(name)} -->\n(.*?)<!-- /{re.escape(name)} -->", text, flags=re.S)


def stale_tables(tables: dict | None = None) -> list[str]:
    """Names of the tables (this file's by default) whose text in their file differs from the generated one, or
    whose markers are missing."""
    stale = []
    for name, (path, make) in (TABLES if tables is None else tables).items():
        found = block(path.read_text(), name) if path.exists() else None
        if found is None or found.group(1) != make() + "\n":
            stale.append(name)
    return stale


def write(tables: dict) -> list[Path]:
    """Replace each table between its markers; nothing is written unless every file has every table's markers."""
    made = {name: (path, make()) for name, (path, make) in tables.items()}
    for name, (path, _) in made.items():
        if block(path.read_text(), name) is None:
            raise ValueError(f"{path} has no <!-- {name} --> ... <!-- /{name} --> block to fill")
    changed = []
    for name, (path, text) in made.items():
        old = path.read_text()
        new = old.replace(block(old, name).group(0), f"<!-- {name} -->\n{text}\n<!-- /{name} -->")
        if new != old:
            path.write_text(new)
            changed.append(path)
    return changed


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="replace the tables in their files")
    parser.add_argument("names", nargs="*", help="only these tables (default: all)")
    args = parser.parse_args(argv)
    tables = all_tables()
    unknown = sorted(set(args.names) - set(tables))
    if unknown:
        parser.error(f"no table named {', '.join(unknown)}; the tables: {', '.join(tables)}")
    tables = {name: tables[name] for name in args.names} if args.names else tables
    if args.write:
        for path in sorted(set(write(tables))):
            print(f"rewrote {path.relative_to(ROOT)}")
        return
    for name, (path, make) in tables.items():
        print(f"{name} ({path.relative_to(ROOT)}):\n{make()}\n")


if __name__ == "__main__":
    main()
