"""Why does the bucket expert fail under action noise? Each failed episode, classified by what the bail did.

    python benchmarks/experts/bucket_expert_failures.py --expert BucketSolver --sigma 0.1 --splits seen unseen \\
        --episodes-per-object 3 --json benchmarks/results/experts/bucket_expert_failures.json

(the committed JSON is of the fingertip-hook expert, ``BucketSolver``; without ``--expert`` the script reads
the task's own expert, the overhand one.)

The same episodes as ``benchmarks/experts/exploration_noise.py`` at one ``sigma`` and seed (episode ``k`` of
object ``i`` reset with seed ``seed + 1000 k + i``, the noise drawn from ``default_rng(seed)`` in the
same order), so the success rate equals that script's row. Every step records the expert's phase
(``Solver.phase``), the bail angle q (rad; -pi/2 lying on the robot's side, 0 upright, +pi/2
lying on the far side) and the body's height over its reset height (m). A failed episode is:

- ``flung over``: q passed ``FLUNG`` (+0.6 rad, the bail toppled beyond upright to the far side,
  where no phase of the expert goes back for it); ``phase`` says in which phase it first did;
- ``fell back``: the bail rose past ``RAISED`` (-1.0 rad) and later sank below ``FELL`` (-1.3 rad),
  back toward the robot's side;
- ``other``: neither (never raised, or raised and lifted without success); ``phase`` is the expert's last phase.

Also reported per episode: the highest lift of the body over its reset height and the body's height
change over the first 20 steps, before the hand arrives (DexArt's reset puts the bucket up to 5 cm above its
nominal height, and it settles); ``regrasps_from``: the phases the expert left for a new approach (its
closed loop's "lost the tube" decisions, in order); and ``lift_swing_rad``: the range (max - min) of q over
the steps of its first lift phase, where the bucket, held by the bail's tube, swings on the frictionless
pivot (None: never lifted). Writes the JSON (per episode, counts per split) and prints a table.
"""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import dataclass, field
from itertools import takewhile

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.experts import SOLVERS, ScriptedPolicy
from dexart_lite.experts.solve import solve_episodes
from dexart_lite.objects import list_objects
from dexart_lite.rollout import noisy, run_episodes
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

FLUNG = 0.6  # rad: past upright toward the far side
RAISED, FELL = -1.0, -1.3  # rad: raised off the wall, then back toward it
SETTLE_STEPS = 20  # control steps before the hand reaches the bail (the approach alone takes ~37)


def classify(trace: list[tuple[str, float, float]]) -> dict:
    """``trace``: (phase, q, body height over the reset height) after each step of a failed episode."""
    phases, q = [p for p, _, _ in trace], np.array([v for _, v, _ in trace])
    flung = np.flatnonzero(q > FLUNG)
    if flung.size:
        return {"failure": "flung over", "phase": phases[flung[0]]}
    raised = np.flatnonzero(q > RAISED)
    if raised.size and (q[raised[0]:] < FELL).any():
        return {"failure": "fell back", "phase": phases[raised[0] + int(np.argmax(q[raised[0]:] < FELL))]}
    return {"failure": "other", "phase": phases[-1]}


def regrasps_from(phases: list[str]) -> list[str]:
    """The phases left for ``approach`` (each a regrasp), in order."""
    return [a for a, b in zip(phases, phases[1:]) if b == "approach" and a != "approach"]


def lift_swing(trace: list[tuple[str, float, float]]) -> float | None:
    """Range of q (rad) over the first run of ``lift`` steps; None if the expert never lifted."""
    phases = [p for p, _, _ in trace]
    if "lift" not in phases:
        return None
    q = [v for _, v, _ in takewhile(lambda step: step[0] == "lift", trace[phases.index("lift"):])]
    return float(max(q) - min(q))


def run_split(split: str, sigma: float, episodes_per_object: int, seed: int, object_names=None,
              expert_name: str | None = None) -> list[dict]:
    env = make("bucket", split=split, object_names=object_names, num_points=32)
    names = env.unwrapped.objects.names
    expert = ScriptedPolicy(env, expert_name)
    policy = noisy(expert, sigma, np.random.default_rng(seed))  # as experts.solve.solve
    traces: list[list] = []

    def on_reset(obs, info):
        traces.append([])

    def on_step(obs, action, reward, next_obs, info, t):
        s = env.unwrapped.state
        traces[-1].append((expert.solver.phase, float(s.q), float(s.base_pos[2] - s.base_pos_at_reset[2])))

    episodes = solve_episodes(names, episodes_per_object, seed)
    results = run_episodes(policy, env, episodes, on_step=on_step, on_reset=on_reset, progress=not fast_mode(),
                           desc=f"bucket/{split}, noise {sigma:g}")
    env.close()
    rows = []
    for episode, trace in zip(results, traces):
        heights = np.array([h for _, _, h in trace])
        row = {"object": episode["object"], "seed": episode["seed"], "success": episode["success"],
               "max_q": float(max(q for _, q, _ in trace)), "max_lift_m": float(heights.max()),
               "settle_m": float(heights[min(SETTLE_STEPS, len(heights)) - 1]),
               "regrasps_from": regrasps_from([p for p, _, _ in trace]), "lift_swing_rad": lift_swing(trace)}
        if not episode["success"]:
            row.update(classify(trace))
        rows.append(row)
    return rows


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    sigma: float = field(default=0.1, metadata={"min": 0.0, "help": "action noise std"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "splits", "episodes_per_object", "seed")
    harness.options(parser, "expert", "json")
    args = parser.parse_args(argv)
    if fast_mode():  # a smoke run of the script itself, not evidence
        args.episodes_per_object = 1

    result = {"task": "bucket", "expert": args.expert or SOLVERS["bucket"].__name__, "sigma": args.sigma,
              "seed": args.seed, "episodes_per_object": args.episodes_per_object,
              "thresholds_rad": {"flung": FLUNG, "raised": RAISED, "fell": FELL}, "splits": {}}
    print("| split | episodes | success | failed: flung over (phase) | fell back | other (last phase) | "
          "body settle, first 20 steps | failed: regrasps from | lift swing of q, median: success / failed |")
    print("|---|---|---|---|---|---|---|---|---|")
    for split in args.splits:
        names = [list_objects("bucket", split)[0].name] if fast_mode() else None
        rows = run_split(split, args.sigma, args.episodes_per_object, args.seed, names, args.expert)
        failed = [r for r in rows if not r["success"]]
        counts = Counter(r["failure"] for r in failed)
        by_phase = {kind: dict(Counter(r["phase"] for r in failed if r["failure"] == kind)) for kind in counts}
        settle = np.array([r["settle_m"] for r in rows])
        lost = Counter(phase for r in failed for phase in r["regrasps_from"])
        swing = {outcome: [r["lift_swing_rad"] for r in rows if r["success"] == ok and r["lift_swing_rad"] is not None]
                 for outcome, ok in (("success", True), ("failed", False))}
        result["splits"][split] = {"episodes": len(rows), "success_rate": float(np.mean([r["success"] for r in rows])),
                                   "failures": dict(counts), "failures_by_phase": by_phase,
                                   "failed_regrasps_from": dict(lost),
                                   "failed_lifted": sum(r["lift_swing_rad"] is not None for r in failed),
                                   "lift_swing_rad_median": {k: float(np.median(v)) if v else None
                                                             for k, v in swing.items()},
                                   "settle_m": {"min": float(settle.min()), "max": float(settle.max())},
                                   "per_episode": rows}
        s = result["splits"][split]
        print(f"| {split} | {len(rows)} | {s['success_rate']:.2f} | {counts.get('flung over', 0)} "
              f"{by_phase.get('flung over', {})} | {counts.get('fell back', 0)} | {counts.get('other', 0)} "
              f"{by_phase.get('other', {})} | {settle.min() * 100:.1f} to {settle.max() * 100:.1f} cm | "
              f"{dict(lost)} | {s['lift_swing_rad_median']['success']} / {s['lift_swing_rad_median']['failed']} |")
    result.update(provenance(__file__, argv))
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return result


if __name__ == "__main__":
    main()
