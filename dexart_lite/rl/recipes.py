"""The recipe behind each task's RL headline: demonstrations -> a DAgger student -> PPO from that student.

    dexart-lite train --task laptop --recipe experts --out runs/laptop_experts            # the README's laptop cell
    dexart-lite train --task laptop --recipe experts --set frames=400000 student.rounds=3  # any field, either stage
    dexart-lite train --task laptop --recipe experts --out runs/laptop_experts            # again: continues

A recipe is two plain configs that hold every setting: the student's ``DistillConfig`` and the learner's
``PPOConfig``. ``--set FIELD=VALUE`` sets a learner field, ``--set student.FIELD=VALUE`` a student one (a name only
the student has may drop the prefix). The pipeline, in ``OUT``:

1. ``student/``: the scripted expert's noisy demonstrations, behaviour cloning, then DAgger rounds in which the
   student drives and the expert labels (``imitation.distill``; an interrupted one continues from its last round);
2. ``rl/``: PPO from the student (``ppo.train`` with ``init_from``), held near it by a KL anchor whose weight decays
   to a floor; a run stopped early (``max_minutes``, Ctrl-C) continues from its checkpoint;
3. the protocol's final evaluation (``rl.evaluate``): deterministic, from the true reset, 10 episodes per seen and
   unseen object at the test seed; ``OUT/recipe.json`` and ``OUT/report.md``.

The experts appear in training only: the policy observes the point cloud and its own state, never the simulator.
Why each setting is what it is, and what else was tried: docs/results/rl_from_experts.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from dexart_lite.imitation.distill import CHECKPOINT as STUDENT_CHECKPOINT
from dexart_lite.imitation.distill import DistillConfig
from dexart_lite.objects import list_objects
from dexart_lite.rl import ppo
from dexart_lite.rl.evaluate import EPISODES_PER_OBJECT, TEST_SEEDS, evaluate_many, split_stats
from dexart_lite.utils import check_choice, fast_mode, parse_overrides, write_json

# PPO from a distilled student (over the `fast` preset): actor lr 3e-5 with a KL early stop at 0.01 per update, a
# small exploration std (log std -2.3: 0.1 in action units), the critic's own lr 1e-3 and its loss kept out of the
# shared trunk, 5 critic-only batches first; a KL penalty to the student (weight 1) that keeps the student's grasp
# while the critic is still wrong; no observation normalisation (the student's inputs were not normalised).
ANCHORED = {"frames_per_batch": 4000, "epochs": 5, "init_log_std": -2.3, "lr": 3e-5, "critic_warmup": 5,
            "critic_detach": True, "reward_scale": 0.01, "critic_lr": 1e-3, "target_kl": 0.01, "anchor_coef": 1.0,
            "obs_norm_steps": 0, "eval_episodes": 3}  # PPO's own end-of-run evaluation: 3 per object at seed 100
# the anchor's weight decays (x 0.95 per batch) to a floor of a tenth: PPO may move away from the student, but not
# drift without bound once the critic is settled
FLOOR = {**ANCHORED, "anchor_decay": 0.95, "anchor_floor": 0.1}
# 4x the frames per update and per gradient step, the same trust region per update, the anchor's schedule per frame
BIG_BATCH = {"frames_per_batch": 16_000, "minibatch": 2_000, "anchor_decay": round(0.95 ** 4, 4), "critic_warmup": 2}
# reward="flat" (a named departure from DexArt's reward): a success pays a fixed bonus at whatever step it comes, so
# the return ranks reliability first instead of early, large openings
FLAT = {"reward": "flat"}
# RFCL's reverse curriculum: episodes start from the expert's states one step before its success on one seeded
# demonstration per training object; a start moves back 5 steps after 3 successes in a row from it
REVERSE = {"curriculum": "reverse", "curriculum_step": 5}


def at_std(settings: dict, std: float) -> dict:
    """``settings`` (anchored, at exploration std 0.1) at exploration std ``std``: between Gaussians of one std the
    KL is sum((delta mu)^2) / (2 std^2), so the anchor's weight and floor scale by (std / 0.1)^2 and the KL early stop
    by its inverse, holding the policy's mean actions as near the student, and moving them as far per update."""
    ratio2 = (std / 0.1) ** 2
    return {**settings, "init_log_std": round(math.log(std), 4), "anchor_coef": settings["anchor_coef"] * ratio2,
            **({"anchor_floor": settings["anchor_floor"] * ratio2} if "anchor_floor" in settings else {}),
            "target_kl": round(settings["target_kl"] / ratio2, 4)}


@dataclasses.dataclass(frozen=True)
class Recipe:
    """One task's pipeline: ``student`` (DistillConfig fields over its defaults) and ``learner`` (PPOConfig fields over
    the `fast` preset); ``run_set``: the name of the measured run set it is (``benchmarks/rl/curriculum_runs.py``
    ``--recipe``, whose JSON holds its figures)."""

    summary: str
    student: dict
    learner: dict
    run_set: str


TWICE_THE_EPISODES = {"demo_episodes_per_object": 9, "episodes_per_round": 4}
RECIPES: dict[str, dict[str, Recipe]] = {
    "laptop": {"experts": Recipe(
        "students from twice the demonstrations, trained on noisy inputs without time and palm velocity; PPO on the "
        "flat bonus with 4x batches, anchored to the student with a floor",
        {**TWICE_THE_EPISODES, "drop_state": "time,palm_velocity", "student_noise": 0.1},
        {**FLOOR, **FLAT, **BIG_BATCH, "frames": 2_000_000},
        "student_anchored_floor_flat_b16k")},
    "faucet": {"experts": Recipe(
        "students from twice the demonstrations; PPO on the flat bonus, anchored to the student with a floor",
        dict(TWICE_THE_EPISODES), {**FLOOR, **FLAT, "frames": 644_000},
        "student_anchored_floor_flat")},
    "toilet": {"experts": Recipe(
        "students from twice the demonstrations that keep only their successful DAgger episodes; PPO at exploration "
        "std 0.05 with the reverse curriculum over one demonstration per seen toilet, anchored with a floor",
        {**TWICE_THE_EPISODES, "drop_failed": True},
        {**at_std({**FLOOR, **REVERSE, "curriculum_demos": 17}, 0.05), "frames": 964_000},
        "student_successonly_anchored_floor_reverse_d17_std05")},
    "bucket": {"experts": Recipe(
        "students of the overhand expert (thumb-first lift) from twice the demonstrations that keep only their "
        "successful DAgger episodes; the laptop's PPO (flat bonus, 4x batches, anchored with a floor) at exploration "
        "std 0.03, since std-0.1 collections lift ~0.05 of the buckets",
        {**TWICE_THE_EPISODES, "drop_failed": True},
        {**at_std({**FLOOR, **FLAT, **BIG_BATCH}, 0.03), "frames": 2_000_000},
        "student_thumbfirst_successonly2x_anchored_floor_flat_b16k_std03")},
}


def recipe(task: str, name: str) -> Recipe:
    check_choice("task", task, RECIPES)
    check_choice(f"{task} recipe", name, RECIPES[task])
    return RECIPES[task][name]


def configs(task: str, name: str, out: str | Path, overrides: list[str] = (), seed: int = 0,
            progress: bool = True) -> tuple[DistillConfig, ppo.PPOConfig]:
    """The student's and the learner's configs of ``task``'s recipe ``name`` in ``out`` (``student/``, ``rl/``),
    with ``overrides`` (``FIELD=VALUE``: the learner's field, else the student's; ``student.FIELD=VALUE``: the
    student's). In fast mode (``DEXART_LITE_FAST=1``) both shrink to a smoke run."""
    r, out = recipe(task, name), Path(out)
    learner_fields = {f.name for f in dataclasses.fields(ppo.PPOConfig)}
    student_fields = {f.name for f in dataclasses.fields(DistillConfig)}
    to_student, to_learner = [], []
    for pair in overrides:
        field = pair.partition("=")[0]
        if field.startswith("student."):
            to_student.append(pair[len("student."):])
        elif field in learner_fields or field not in student_fields:  # unknown: the learner's error names its fields
            to_learner.append(pair)
        else:
            to_student.append(pair)
    student = {**r.student, "task": task, "seed": seed, "progress": progress, "out": str(out / "student")}
    learner = {**r.learner, "task": task, "obs": "cloud", "seed": seed, "progress": progress, "out": str(out / "rl"),
               "init_from": str(out / "student" / STUDENT_CHECKPOINT)}
    if fast_mode():  # a smoke run of the pipeline, not evidence
        student.update(num_points=64, max_episode_steps=10, demo_episodes_per_object=1, rounds=1, episodes_per_round=1,
                       epochs=1, epochs_per_round=1, eval_episodes=1, objects=list_objects(task, "seen")[0].name)
        learner.update(frames_per_batch=200, minibatch=100, epochs=1, num_points=64, max_episode_steps=30,
                       eval_episodes=1, frames=400, critic_warmup=1, curriculum_demos=2)
    student.update(parse_overrides(to_student, DistillConfig))
    learner.update(parse_overrides(to_learner, ppo.PPOConfig))
    return DistillConfig(**student), ppo.preset("fast", **learner)


def train_recipe(task: str, name: str, out: str | Path, overrides: list[str] = (), seed: int = 0,
                 episodes_per_object: int | None = None, progress: bool = True) -> dict:
    """The whole pipeline (module docstring), each stage read back or continued where it already ran; the result
    (``OUT/recipe.json``) and ``OUT/report.md``."""
    from dexart_lite.study import run_arm

    out = Path(out)
    student_cfg, learner_cfg = configs(task, name, out, overrides, seed, progress)
    student = run_arm(student_cfg)
    learner = run_arm(learner_cfg)
    episodes = episodes_per_object or (1 if fast_mode() else EPISODES_PER_OBJECT)
    checkpoint = str(Path(learner_cfg.out) / ppo.CHECKPOINT)
    final = evaluate_many([(checkpoint, split) for split in ("seen", "unseen")], episodes, TEST_SEEDS[0])
    result = {"task": task, "recipe": name, "seed": seed, "summary": recipe(task, name).summary,
              "student": {"config": dataclasses.asdict(student_cfg), "seen_success": student["seen_success"],
                          "unseen_success": student["unseen_success"]},
              "learner": {"config": dataclasses.asdict(learner_cfg), "frames": learner["frames"]},
              "final_evaluation": {"env_seed": TEST_SEEDS[0], "episodes_per_object": episodes,
                                   **{split: split_stats(final[(checkpoint, split)]) for split in ("seen", "unseen")}}}
    write_json(out / "recipe.json", result)
    (out / "report.md").write_text(report(result))
    return result


def report(result: dict) -> str:
    final, student = result["final_evaluation"], result["student"]
    rows = [f"| {split} | {student[f'{split}_success']:.2f} | {final[split]['success']:.2f} ± {final[split]['se']:.2f} |"
            for split in ("seen", "unseen")]
    return "\n".join([
        f"# {result['task']}: recipe `{result['recipe']}`, seed {result['seed']}", "", result["summary"] + ".", "",
        f"PPO trained {result['learner']['frames']:,} online frames from the student (`student/`, `rl/`).", "",
        f"Final evaluation: deterministic, from the true reset, {final['episodes_per_object']} episodes per object at "
        f"env seed {final['env_seed']} (the test seed). The student's column is its own evaluation (its "
        f"`eval_episodes` per object at env seed {student['config']['eval_seed']}).", "",
        "| split | student | RL (± object-stratified se of the episodes) |", "|---|---|---|", *rows, ""])


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--recipe", default=None, help="a task's pipeline from the experts: demonstrations, a DAgger "
                        "student, PPO from it, the final evaluation (" + "; ".join(
                            f"{t}: {', '.join(r)}" for t, r in RECIPES.items()) + "); with --task, --out, --set")


def run(args: argparse.Namespace) -> int:
    """``dexart-lite train --recipe NAME``: the flags given (other than task, out, seed) and ``--set`` pairs become
    the recipe's overrides."""
    if args.task is None:
        raise ValueError(f"--recipe needs --task (one of {', '.join(RECIPES)})")
    recipe(args.task, args.recipe)  # a wrong name fails before anything is built
    flags = [f"{f.name}={getattr(args, f.name)}" for f in dataclasses.fields(ppo.PPOConfig)
             if f.name not in ("task", "out", "seed") and getattr(args, f.name, None) is not None]
    out = args.out or f"runs/{args.task}_{args.recipe}"
    result = train_recipe(args.task, args.recipe, out, [*flags, *(args.overrides or [])], args.seed or 0)
    final = result["final_evaluation"]
    print(f"{result['task']} {result['recipe']}: student {result['student']['seen_success']:.2f} / "
          f"{result['student']['unseen_success']:.2f}, RL {final['seen']['success']:.2f} / "
          f"{final['unseen']['success']:.2f} (test seed, {final['episodes_per_object']} per object) -> {out}/report.md")
    return 0

