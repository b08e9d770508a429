"""How learnable is each task's reward apart from perception? PPO on the state-only diagnostic, per task.

    python benchmarks/rl/state_diagnostic.py --tasks faucet laptop toilet bucket --seeds 0 1 --frames 300000 \
        --json benchmarks/results/rl/state_diagnostic.json
    python benchmarks/rl/state_diagnostic.py --preset fast --tasks faucet laptop --seeds 0 1 --frames 300000 \
        --json benchmarks/results/rl/state_diagnostic_fast.json
    python benchmarks/rl/state_diagnostic.py --preset fast_sil --tasks faucet --seeds 0 1 --frames 300000 \
        --json benchmarks/results/rl/state_diagnostic_fast_sil_faucet.json      # and --tasks laptop ..._laptop.json

Every task x seed is one ``benchmarks/rl/bench_learning.py`` run with ``--obs state`` (the state vector plus
the privileged object state: the part's pose, joint angle, initial angle, target and grasp point; no
camera, an MLP policy) and the settings below, written as ``learning_<task>_state_<tag>_s<seed>.json``
next to the other learning results (tag ``dexart`` for ``--preset cpu``: DexArt's reward; ``fast``). A run whose JSON already holds these settings is read back, not
repeated (the two laptop seeds of docs/results/ppo.md's state-only section are such runs). Runs go one after the
other, alone.

Reported per task: **frames to first success** (the first PPO batch whose collected, stochastic episodes
contain a success; None if none did), frames to the first step in stage 3 (the grasp/manipulation
stage), and the deterministic evaluation's success on the seen and unseen objects at the end. The
settings (``--preset cpu``) are the cpu preset's (4k frames per batch, 5 epochs) with the departures the
laptop runs used: lr 3e-4 (DexArt 1e-4), rewards x 0.01 (DexArt 1), initial action std 0.3 (log-std -1.2;
DexArt 0). ``--preset fast`` is the PPO preset of that name: the same settings plus a fixed input
normalisation from 2,000 steps of the initial policy (``obs_norm_steps``), so the two compare that one change.
``--preset fast_sil`` is ``fast`` plus self-imitation learning (``sil_coef=1``, ``rl/sil.py``): one more change.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.ppo import PRESETS, PPOConfig  # noqa: E402
from dexart_lite.utils import (benchmark_results, fast_mode, parse_overrides, provenance, save_figure,  # noqa: E402
                               sibling_script, write_json)

RESULTS = benchmark_results(__file__)
harness = sibling_script(__file__, "_harness")
# --preset cpu: departures from the cpu preset, as the laptop state-only runs of docs/results/ppo.md (bench_learning
# --set and --init-log-std); --preset fast: the fast preset, which holds them, on the state observation
SETTINGS = {"cpu": ["obs=state", "lr=3e-4", "reward_scale=0.01"], "fast": ["obs=state"],
            "fast_sil": ["obs=state", "sil_coef=1.0"], "fast_synergy": ["obs=state", "hand=synergy"]}
# the PPO preset each setting starts from
PPO_PRESET = {"cpu": "cpu", "fast": "fast", "fast_sil": "fast", "fast_synergy": "fast"}
INIT_LOG_STD = -1.2
# learning_<task>_state_<tag>_s<seed>.json
TAGS = {"cpu": "dexart", "fast": "fast", "fast_sil": "fast_sil", "fast_synergy": "fast_synergy"}
DEPARTURES = {"cpu": "state-only observation (diagnostic), lr 3e-4 (1e-4), rewards x 0.01 (x 1), initial log-std "
                     "-1.2 (0), 4k frames per batch (20k), 5 epochs (10)"}
DEPARTURES["fast"] = (DEPARTURES["cpu"] + ", inputs normalised with the statistics of 2,000 steps of the initial "
                      "policy (raw inputs)")
DEPARTURES["fast_sil"] = (DEPARTURES["fast"] + ", self-imitation of the best 20k collected steps at weight 1 "
                          "(no replay)")
DEPARTURES["fast_synergy"] = (DEPARTURES["fast"] + ", a 9-D action: the palm twist and 3 hand synergies, "
                              "robot.synergy_targets (22-D: 16 hand joint targets)")


def run_tag(seed: int, preset: str = "cpu") -> str:
    """bench_learning's ``--tag``: the run's JSON is ``learning_<task>_<tag>.json``."""
    return f"state_{TAGS[preset]}_s{seed}"


def run_args(task: str, seed: int, frames: int, eval_episodes: int, results: Path, out: Path,
             preset: str = "cpu") -> list[str]:
    """The ``bench_learning.py`` arguments of one task and seed."""
    log_std = ["--init-log-std", str(INIT_LOG_STD)] if preset == "cpu" else []  # fast: the preset's own
    return ["--task", task, "--preset", PPO_PRESET[preset], "--seed", str(seed), "--tag", run_tag(seed, preset),
            "--eval-episodes", str(eval_episodes), "--set", *SETTINGS[preset], *log_std,
            "--frames", str(frames), "--results", str(results), "--out", str(out)]


def finished(path: Path, frames: int, eval_episodes: int, preset: str = "cpu") -> dict | None:
    """The JSON of an earlier run with exactly these settings, or None."""
    if not path.is_file():
        return None
    summary = json.loads(path.read_text())
    cfg = summary.get("config", {})
    same = (summary.get("frames") == frames and summary.get("preset") == PPO_PRESET[preset]
            and summary.get("eval_episodes_per_object") == eval_episodes
            and summary.get("departures_from_preset") == parse_overrides(SETTINGS[preset], PPOConfig)
            and cfg.get("init_log_std") == INIT_LOG_STD and cfg.get("reward", "dexart") == "dexart"
            and cfg.get("obs_norm_steps", 0) == PRESETS[PPO_PRESET[preset]].get("obs_norm_steps", 0))
    return summary if same else None


def first_frames(points: list[dict], key: str) -> int | None:
    """Frames at the end of the first batch whose ``key`` (collected episodes / steps) is above zero."""
    return next((p["frames"] for p in points if p[key] > 0), None)


def summarise_run(summary: dict, seed: int, read_back: bool) -> dict:
    points = summary["curve_points"]
    return {"seed": seed, "frames": summary["frames"],
            "frames_to_first_success": first_frames(points, "success_rate"),
            "frames_to_first_stage3": first_frames(points, "stage3_frac"),
            "best_batch_success": max(p["success_rate"] for p in points),
            "seen_success": summary["seen_success"], "unseen_success": summary["unseen_success"],
            "seen_mean_max_stage": summary["seen_mean_max_stage"],
            "unseen_mean_max_stage": summary["unseen_mean_max_stage"],
            "wall_time_s": summary["wall_time_s"], "collect_fps": summary["collect_fps"],
            "read_back": read_back, "curve": [(p["frames"], p["success_rate"]) for p in points]}


def plot(result: dict, path: Path) -> None:
    """Success of the collected episodes per batch against frames, one panel per task, one line per seed."""
    tasks = list(result["tasks"])
    fig, axes = plt.subplots(1, len(tasks), figsize=(3.6 * len(tasks), 3.2), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        for run in result["tasks"][task]["per_seed"]:
            frames, success = zip(*([(0, 0.0)] + [tuple(p) for p in run["curve"]]))
            ax.plot(frames, success, label=f"seed {run['seed']}")
        ax.set(title=f"{task} (state only, {result['settings']['preset']})", xlabel="frames", ylim=(-0.02, 1.02))
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("success of collected episodes")
    save_figure(fig, path)


def state_run(frames: int, eval_episodes: int, preset: str, results: Path, task: str, seed: int) -> dict:
    """One task and seed: ``bench_learning.py``'s run, or its JSON read back when one with these settings exists."""
    name = f"learning_{task}_{run_tag(seed, preset)}"
    summary = None if fast_mode() else finished(results / f"{name}.json", frames, eval_episodes, preset)
    if summary is not None:
        return summarise_run(summary, seed, read_back=True)
    runs_dir = results / "runs" if fast_mode() else Path("runs")  # a smoke run stays beside its JSON
    bench = sibling_script(__file__, "bench_learning")
    summary = bench.main(run_args(task, seed, frames, eval_episodes, results, runs_dir / name, preset))
    return summarise_run(summary, seed, read_back=False)


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    preset: str = field(default="cpu", metadata={"choices": list(SETTINGS), "help": "cpu: DexArt's PPO with the "
                        "departures above; fast: plus the input normalisation; fast_sil: plus self-imitation learning; "
                        "fast_synergy: fast with the 3-synergy hand"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks", seeds=[0, 1], frames=300_000, eval_episodes=2)
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, json=RESULTS / "state_diagnostic.json")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    grid = [{"task": task, "seed": seed} for task in args.tasks for seed in args.seeds]
    rows = list(harness.each(functools.partial(state_run, args.frames, args.eval_episodes, args.preset,
                                               args.json.parent), grid, desc="runs"))
    tasks = {}
    for task in args.tasks:
        runs = [row for params, row in zip(grid, rows) if params["task"] == task]
        firsts = [r["frames_to_first_success"] for r in runs]
        tasks[task] = {"per_seed": runs, "frames_to_first_success": firsts,
                       "seeds_with_a_success": sum(f is not None for f in firsts),
                       "seen_success": sum(r["seen_success"] for r in runs) / len(runs),
                       "unseen_success": sum(r["unseen_success"] for r in runs) / len(runs)}
    result = {"frames": args.frames, "seeds": args.seeds, "eval_episodes_per_object": args.eval_episodes,
              "settings": {"preset": args.preset, "set": SETTINGS[args.preset], "init_log_std": INIT_LOG_STD,
                           "departures_from_dexart": DEPARTURES[args.preset]},
              "tasks": tasks, "wall_time_s": time.perf_counter() - start,
              "wall_time_note": "this invocation only; each run's own training time is in per_seed",
              **provenance(__file__, argv)}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, result)
    plot(result, args.json.with_suffix(".png"))
    print("| task | frames | frames to first success (per seed) | seen / unseen success (mean) |\n|---|---|---|---|")
    for task, t in tasks.items():
        firsts = ", ".join("none" if f is None else f"{f:,}" for f in t["frames_to_first_success"])
        print(f"| {task} | {args.frames:,} | {firsts} | {t['seen_success']:.2f} / {t['unseen_success']:.2f} |")
    print(f"wrote {args.json} and {args.json.with_suffix('.png')}")
    return result


if __name__ == "__main__":
    main()
