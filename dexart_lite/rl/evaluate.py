"""Evaluate a PPO policy on the seen or unseen objects of a task, as DexArt does.

    dexart-lite eval --ckpt runs/laptop/checkpoint.pt --split unseen --episodes-per-object 10 --seed 100 --json out.json

Protocol (DexArt ``examples/evaluate_policy.py``): deterministic actions (the Gaussian's mean);
the env keeps its point-cloud noise, camera-pose noise and object-pose randomisation; rounds of one
episode per object, each object chosen explicitly with ``reset(options={"object": name})``; an
episode is a success if it succeeds at any step. Reported per object and overall: success rate,
mean highest stage reached (1 reach, 2 contact, 3 manipulate) and mean return. The env RNG is
seeded once with ``--seed``, so a run is reproducible.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Callable

from torchrl.modules import ActorValueOperator

from dexart_lite import objects as objects_lib
from dexart_lite import render
from dexart_lite.envs import make as make_gym_env
from dexart_lite.registration import TASKS
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint, observation_kwargs, policy_function
from dexart_lite.rl.env import torch_threads
from dexart_lite.rollout import per_object_summary, run_episodes
from dexart_lite.utils import check_choice, process_pool, resolve_device, sigterm_interrupts, write_json

SPLITS = ("seen", "unseen", "seen_half")


def evaluate(actor_critic: ActorValueOperator, task: str, split: str = "seen", episodes_per_object: int = 10,
             seed: int = 100, env_kwargs: dict | None = None, device: torch.device | None = None,
             prepare_env: Callable | None = None) -> dict:
    """Success per object and overall; see the module docstring. ``env_kwargs`` go to the gymnasium env
    (``dexart_lite.envs.make``); the episodes run in the rollout layer (``dexart_lite.rollout``). ``device``:
    where the network acts (None: where it is; one observation at a time, so the CPU is usually fastest).
    ``prepare_env``: called with the unwrapped env before its first reset (a diagnostic's hook, e.g. the tank
    eraser of ``benchmarks/students/tank_ablation.py``)."""
    if device is not None:
        actor_critic.to(device)
    return evaluate_policy(lambda env: policy_function(actor_critic, device), task, split, episodes_per_object,
                           seed, env_kwargs, prepare_env)


def evaluate_policy(make_policy: Callable, task: str, split: str = "seen", episodes_per_object: int = 10,
                    seed: int = 100, env_kwargs: dict | None = None, prepare_env: Callable | None = None) -> dict:
    """``evaluate`` of any policy: ``make_policy(env)`` returns the function from observations to actions (a
    network's, or a scripted expert's, which reads the env it is given)."""
    check_choice("split", split, SPLITS)
    if episodes_per_object < 1:
        raise ValueError(f"episodes_per_object must be >= 1, got {episodes_per_object}")
    names = [info.name for info in objects_lib.list_objects(task, split)]
    env = make_gym_env(task, split=split, **{"point_noise": True, "camera_noise": True, **(env_kwargs or {})})
    if prepare_env is not None:
        prepare_env(env.unwrapped)
    # The env RNG is seeded once, by a reset (as torchrl's set_seed did when evaluations ran through
    # torchrl: the committed evaluations replay episode for episode); the episodes draw from it in turn.
    env.reset(seed=seed)
    rounds = [(None, name) for _ in range(episodes_per_object) for name in names]
    start = time.perf_counter()
    with torch_threads(1):
        episodes = run_episodes(make_policy(env), env, rounds)
    env.close()
    return {"task": task, "split": split, "episodes_per_object": episodes_per_object, "seed": seed,
            **per_object_summary(episodes), "wall_time_s": round(time.perf_counter() - start, 1)}


def evaluate_expert(task: str, split: str = "seen", episodes_per_object: int = 10, seed: int = 100) -> dict:
    """``evaluate`` of the task's scripted expert (privileged: it reads the simulator), on the same episodes a
    policy is evaluated on at ``seed``."""
    from dexart_lite.experts import ScriptedPolicy

    result = evaluate_policy(ScriptedPolicy, task, split, episodes_per_object, seed)
    return {**result, "checkpoint": None, "frames": 0, "device": "cpu"}


def evaluate_splits(policy, cfg, out: Path) -> list[dict]:
    """``evaluate`` on the seen and the unseen objects with a run's evaluation settings (``cfg``: any config with
    ``task``, ``eval_episodes``, ``eval_seed`` and ``env_kwargs()``: PPO, SAC, distillation); writes
    ``out/eval_<split>.json``. None when ``cfg.eval_episodes`` is 0."""
    evals = []
    for split in ("seen", "unseen") if cfg.eval_episodes > 0 else ():
        result = evaluate(policy, cfg.task, split, cfg.eval_episodes, cfg.eval_seed, cfg.env_kwargs())
        write_json(Path(out) / f"eval_{split}.json", result)
        evals.append(result)
    return evals


def markdown_table(results: list[dict]) -> str:
    """One row per object and an overall row per result of ``evaluate``."""
    lines = ["| split | object | success | mean max stage | mean return | episodes |", "|---|---|---|---|---|---|"]
    for res in results:
        for name, r in res["objects"].items():
            lines.append(f"| {res['split']} | {name} | {r['success_rate']:.2f} | {r['mean_max_stage']:.2f} | "
                         f"{r['mean_return']:.1f} | {r['episodes']} |")
        lines.append(f"| {res['split']} | **all** | **{res['success_rate']:.2f}** | {res['mean_max_stage']:.2f} | "
                     f"{res['mean_return']:.1f} | {res['episodes']} |")
    return "\n".join(lines)


def record_gif(actor_critic: ActorValueOperator, task: str, path: str | Path, split: str = "seen",
               object_name: str | None = None, seed: int = 100, env_kwargs: dict | None = None) -> dict:
    """Render one deterministic evaluation episode to a GIF; returns its summary."""
    env = make_gym_env(task, split=split, render_mode="rgb_array",
                       **{"point_noise": True, "camera_noise": True, **(env_kwargs or {})})
    options = {"object": object_name} if object_name else None
    with torch_threads(1):
        frames, summary = render.record_episode(env, policy_function(actor_critic), seed=seed, options=options)
    env.close()
    render.save_gif(frames, path)
    return {**summary, "path": str(path)}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--ckpt", required=True,
                        help="checkpoint written by `dexart-lite train` or `distill`, or zoo:<task> (a shipped policy)")
    parser.add_argument("--split", default="seen", help=f"one of {', '.join(SPLITS)}")
    parser.add_argument("--episodes-per-object", type=int, default=10, help="DexArt uses 100")
    parser.add_argument("--seed", type=int, default=100, help="env seed (DexArt: 100)")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--gif", type=Path, help="also save one evaluation episode as a GIF")
    parser.add_argument("--device", default="cpu", help="where the policy acts: cpu, cuda or auto (cuda where "
                        "there is one); one observation at a time, so the CPU is usually fastest")


def load_policy(path: str | Path) -> tuple[ActorValueOperator, dict, dict]:
    """The policy saved at ``path`` (a PPO or distillation checkpoint, loaded strictly), its run config
    and the env keywords of the observation it was trained on."""
    payload = load_checkpoint(path)
    cfg = payload["config"]
    check_choice("task", cfg["task"], TASKS)
    env_kwargs = observation_kwargs(payload)
    if cfg.get("max_episode_steps"):
        env_kwargs["max_episode_steps"] = cfg["max_episode_steps"]
    return actor_critic_from_checkpoint(payload, path), {**cfg, "frames": payload["frames"]}, env_kwargs


def evaluate_checkpoint(path: str | Path, split: str = "seen", episodes_per_object: int = 10,
                        seed: int = 100, device: str = "cpu") -> dict:
    """``evaluate`` of the policy saved at ``path`` on ``device`` (cpu, cuda or auto); the result also names
    the checkpoint, its training frames and the device. A plain function of its arguments, so that a
    process pool can run several."""
    check_choice("split", split, SPLITS)
    chosen = resolve_device(device)
    actor_critic, cfg, env_kwargs = load_policy(path)
    result = evaluate(actor_critic, cfg["task"], split, episodes_per_object, seed, env_kwargs, chosen)
    return {**result, "checkpoint": str(path), "frames": cfg["frames"], "device": chosen.type}


def heldout_path(checkpoint: str | Path, split: str, episodes_per_object: int, seed: int) -> Path:
    """Where ``evaluate_many`` keeps one evaluation: next to the checkpoint, ``heldout_<split>_e<N>_seed<S>.json``."""
    return Path(checkpoint).parent / f"heldout_{split}_e{episodes_per_object}_seed{seed}.json"


def heldout_current(cache: Path, checkpoint: Path) -> bool:
    """Whether a cached evaluation (``heldout_path``) still measures ``checkpoint``: it exists and is not older than
    the checkpoint (one trained on since is evaluated again)."""
    return cache.exists() and not (checkpoint.exists() and checkpoint.stat().st_mtime > cache.stat().st_mtime)


def split_stats(result: dict) -> dict:
    """Success, its standard error and success per object, of one ``evaluate`` result. Every object gets the same k
    episodes, so the se is stratified by object: sqrt(sum_o p_o (1 - p_o) / k) / n_objects."""
    per_object = {name: r["success_rate"] for name, r in result["objects"].items()}
    k = result["episodes_per_object"]
    se = math.sqrt(sum(p * (1 - p) / k for p in per_object.values())) / len(per_object)
    return {"success": result["success_rate"], "se": se, "objects": per_object}


def evaluate_many(work: list[tuple[str, str]], episodes_per_object: int, seed: int, jobs: int = 1) -> dict:
    """``evaluate_checkpoint`` of every (checkpoint, split) in ``work`` with ``episodes_per_object`` at env seed
    ``seed``, ``jobs`` at a time (success does not depend on timing, so evaluations may run side by side), with a
    progress bar. Each result is cached next to its checkpoint (``heldout_path``) and read back from there by a
    later call, unless the checkpoint is newer than it. Returns {(checkpoint, split): result}."""
    from concurrent.futures import as_completed

    from tqdm import tqdm

    work = list(dict.fromkeys((str(c), s) for c, s in work))
    todo = [(c, s) for c, s in work if not heldout_current(heldout_path(c, s, episodes_per_object, seed), Path(c))]
    bar = tqdm(total=len(todo), desc="evaluations", unit="eval", disable=not todo)
    if jobs <= 1:
        for c, s in todo:
            write_json(heldout_path(c, s, episodes_per_object, seed), evaluate_checkpoint(c, s, episodes_per_object, seed))
            bar.update()
    else:  # spawned workers (pybullet and torch do not survive a fork of a busy parent), stopped with the caller
        with sigterm_interrupts(), process_pool(jobs) as pool:
            futures = {pool.submit(evaluate_checkpoint, c, s, episodes_per_object, seed): (c, s) for c, s in todo}
            for future in as_completed(futures):
                write_json(heldout_path(*futures[future], episodes_per_object, seed), future.result())
                bar.update()
    bar.close()
    return {(c, s): json.loads(heldout_path(c, s, episodes_per_object, seed).read_text()) for c, s in work}


def run(args: argparse.Namespace) -> int:
    result = evaluate_checkpoint(args.ckpt, args.split, args.episodes_per_object, args.seed, args.device)
    print(f"{result['task']} {args.split}: {result['frames']} training frames, {result['episodes']} episodes, "
          f"{result['wall_time_s']} s")
    print(markdown_table([result]))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2))
        print(f"wrote {args.json}")
    if args.gif:
        actor_critic, cfg, env_kwargs = load_policy(args.ckpt)
        gif = record_gif(actor_critic, cfg["task"], args.gif, args.split, seed=args.seed, env_kwargs=env_kwargs)
        print(f"wrote {args.gif} ({gif['object_name']}, success {gif['success']})")
    return 0


# ---- The one evaluation protocol of every reported figure (experts, students, RL, state diagnostics) ----------
# Deterministic actions from the true reset, EPISODES_PER_OBJECT episodes per seen and per unseen object, at the env
# seed of one of two disjoint sets:
# - validation (VALIDATION_SEEDS): every choice (a checkpoint, a recipe, the seed a zoo entry ships) is made on these,
#   and on the seen objects alone: unseen objects never steer a choice. New validation evaluations use the first;
#   1000 is in the set because earlier checkpoint sweeps chose on it, so it can no longer be a test.
# - test (TEST_SEEDS): each reported cell is evaluated on it once, after every choice is made, and never chooses.
EPISODES_PER_OBJECT = 10
VALIDATION_SEEDS = (100, 1000)
TEST_SEEDS = (7919,)  # a seed no earlier evaluation of the repository used


def check_phase_seed(phase: str, seed: int) -> int:
    """``seed`` if it belongs to ``phase`` ("validation" or "test"); a one-line error naming the phase's seeds
    otherwise. Every script that chooses calls it with "validation", so a test seed cannot steer a choice."""
    seeds = {"validation": VALIDATION_SEEDS, "test": TEST_SEEDS}
    check_choice("phase", phase, tuple(seeds))
    if seed not in seeds[phase]:
        raise ValueError(f"env seed {seed} is not a {phase} seed; {phase} seeds: "
                         f"{', '.join(map(str, seeds[phase]))} (validation chooses, test reports)")
    return seed


def over_seeds(values: list[float]) -> dict:
    """A cell's figure: the mean over training seeds, its standard error over them (sample std / sqrt(n); 0 for one
    seed) and the per-seed values beside it."""
    if not values:
        raise ValueError("no seed to summarise")
    n, mean = len(values), sum(values) / len(values)
    se = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1) / n) if n > 1 else 0.0
    return {"mean": mean, "se": se, "per_seed": list(values), "seeds": n}


def protocol_evaluation(checkpoints: dict[int, str | Path], phase: str = "test", jobs: int = 1,
                        episodes_per_object: int = EPISODES_PER_OBJECT) -> dict:
    """Every checkpoint of ``checkpoints`` ({training seed: file}) on the seen and the unseen objects at the first
    seed of ``phase`` (cached beside each file by ``evaluate_many``): per split the cell (``over_seeds``), and per
    training seed its success and the object-stratified se of its episodes."""
    seed = (VALIDATION_SEEDS if phase == "validation" else TEST_SEEDS)[0]
    check_phase_seed(phase, seed)
    splits = ("seen", "unseen")
    results = evaluate_many([(str(c), s) for c in checkpoints.values() for s in splits], episodes_per_object, seed,
                            jobs)
    task = next(iter(results.values()))["task"]
    out = {"phase": phase, "env_seed": seed, "episodes_per_object": episodes_per_object}
    for split in splits:
        stats = [split_stats(results[(str(c), split)]) for c in checkpoints.values()]
        objects = {name: [s["objects"][name] for s in stats] for name in stats[0]["objects"]}  # per training seed
        out[split] = {**over_seeds([s["success"] for s in stats]), "training_seeds": list(checkpoints),
                      "episode_se": [s["se"] for s in stats], "objects": objects,
                      "templates": by_template(task, split, {n: sum(v) / len(v) for n, v in objects.items()})}
    out["frames"] = [results[(str(c), "seen")]["frames"] for c in checkpoints.values()]
    return out


def by_template(task: str, split: str, per_object: dict[str, float]) -> dict:
    """Success of one split per object template, read from the objects' metadata (no template is named here): each
    template's mean over its objects, and for the unseen split its two halves as DexArt's unseen split is built:
    ``held_out_bands`` (objects of a template the seen split has, with a parameter in a held-out band) and
    ``held_out_template`` (objects of a template no seen object has)."""
    infos = {o.name: o for o in objects_lib.list_objects(task, split)}
    seen_templates = {o.template for o in objects_lib.list_objects(task, "seen")}
    groups: dict[str, list[str]] = {}
    for name in per_object:
        groups.setdefault(f"template {infos[name].template}", []).append(name)
        if split == "unseen":
            half = "held_out_bands" if infos[name].template in seen_templates else "held_out_template"
            groups.setdefault(half, []).append(name)
    return {group: {"success": sum(per_object[n] for n in names) / len(names), "objects": len(names)}
            for group, names in sorted(groups.items())}


def choose_headline(candidates: list[dict], budget_frames: int) -> dict:
    """The rule that picks a task's headline: among ``candidates`` (each {"name", "frames": per-seed frames,
    "validation": {"seen": per-seed success at a validation seed}}) whose every seed trained at most
    ``budget_frames``, the best mean validation success on the seen objects; a tie goes to fewer frames, then to the
    name. Reads nothing but those fields: no unseen object and no test seed enters the choice."""
    within = [c for c in candidates if max(c["frames"]) <= budget_frames]
    if not within:
        raise ValueError(f"no candidate within the budget of {budget_frames} frames (of {len(candidates)})")
    return min(within, key=lambda c: (-over_seeds(c["validation"]["seen"])["mean"], max(c["frames"]), c["name"]))
