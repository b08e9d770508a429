"""Where distilled students fail: failure stage per episode, the expert's disagreement, and action noise.

    python benchmarks/students/student_failures.py --runs runs/distill_laptop_dagger_s0 runs/distill_laptop_dagger_s1 \
        --sigmas 0 0.1 0.2 --json benchmarks/results/students/student_failures_laptop.json

For each student (a ``dexart-lite distill`` folder with ``checkpoint.pt``), each split and each
noise std ``sigma`` (Gaussian noise added to the student's deterministic action, as
``rollout.noisy``), it runs ``--episodes-per-object`` episodes on every object with the student's
own env settings and counts how the failed episodes ended:

- ``no_contact``: never reached stage 2 (the hand never came close to the part);
- ``touched``: stage 2 but never stage 3 (close to or touching the part, never a grasp);
- ``grasped``: reached stage 3 (grasping the part) but did not finish the task.

At every step the scripted expert also labels the student's state (it does not act), giving
``arm_error`` / ``hand_error``: the mean absolute difference between the student's and the
expert's action on the 6 arm and the 16 hand dimensions (action units), the compounding-error
signal of DAgger. ``stalled_frac`` is the fraction of failed episodes' last 100 steps in which
the palm moved less than 2 mm per control step (a student stuck at a fixed point), and
``stalled_by_region`` splits those stalled steps by the rule the expert's law would apply there
(``FeedbackLidSolver.region`` on laptops and toilets: approach, lift, wrap, close, ride; the phase
of the other experts), as fractions of all stalled steps: where in the task the students stop.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.experts.solve import solve_episodes
from dexart_lite.imitation.distill import DistillConfig
from dexart_lite.objects import list_objects
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint, policy_function
from dexart_lite.rollout import noisy, run_episodes
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

STALL_M = 0.002  # m of palm travel per control step below which a step counts as stalled
CLASSES = ("success", "no_contact", "touched", "grasped")


def outcome(episode: dict) -> str:
    if episode["success"]:
        return "success"
    return {1: "no_contact", 2: "touched"}.get(episode["max_stage"], "grasped")


def run_student(run: Path, split: str, sigma: float, episodes_per_object: int, seed: int,
                max_steps: int | None = None) -> dict:
    payload = load_checkpoint(run / "checkpoint.pt")
    cfg = DistillConfig(**payload["config"])
    kwargs = cfg.env_kwargs()
    if max_steps:
        kwargs["max_episode_steps"] = max_steps
    env = make(cfg.task, split=split, **kwargs)
    student = noisy(policy_function(actor_critic_from_checkpoint(payload, run / "checkpoint.pt")), sigma,
                    np.random.default_rng(seed))
    expert = ScriptedPolicy(env)

    def act(obs):  # the expert labels the state the student acts on (it reads the env, so before the step)
        trace["label"] = expert(obs)
        trace["region"][-1].append(getattr(expert.solver, "region", expert.solver.phase))
        return student(obs)

    act.reset = student.reset  # the expert restarts by itself at step 0 (ScriptedPolicy)
    names = [o.name for o in list_objects(cfg.task, split)]
    if fast_mode():
        names = names[:1]
    episodes = solve_episodes(names, episodes_per_object, seed)
    trace: dict = {"arm": [], "hand": [], "palm": [], "region": []}

    def on_reset(obs, info):
        trace["palm"].append([obs["state"][28:31].copy()])
        for key in ("arm", "hand", "region"):
            trace[key].append([])

    def on_step(obs, action, reward, next_obs, info, t):
        label = trace["label"]  # the expert's action at the student's state (the expert does not act)
        trace["arm"][-1].append(np.abs(student.label[:6] - label[:6]).mean())
        trace["hand"][-1].append(np.abs(student.label[6:] - label[6:]).mean())
        trace["palm"][-1].append(next_obs["state"][28:31].copy())

    start = time.perf_counter()
    results = run_episodes(act, env, episodes, on_step=on_step, on_reset=on_reset)
    env.close()
    counts = {c: 0 for c in CLASSES}
    stalled, stalled_regions = [], Counter()
    for ep, palm, regions in zip(results, trace["palm"], trace["region"]):
        counts[outcome(ep)] += 1
        if not ep["success"]:
            still = np.linalg.norm(np.diff(np.asarray(palm), axis=0), axis=1)[-100:] < STALL_M  # step t moved the palm
            stalled.append(float(np.mean(still)))
            stalled_regions.update(r for r, s in zip(regions[-100:], still) if s)
    n_stalled = sum(stalled_regions.values())
    n = len(results)
    return {"run": str(run), "task": cfg.task, "split": split, "sigma": sigma, "episodes": n,
            "success_rate": counts["success"] / n, **{f"{c}_frac": counts[c] / n for c in CLASSES[1:]},
            "arm_error": float(np.mean([e for ep in trace["arm"] for e in ep])),
            "hand_error": float(np.mean([e for ep in trace["hand"] for e in ep])),
            "stalled_frac": float(np.mean(stalled)) if stalled else 0.0,
            "stalled_by_region": {r: c / n_stalled for r, c in sorted(stalled_regions.items())},
            "wall_time_s": round(time.perf_counter() - start, 1)}


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    runs: list[Path] = field(default_factory=list, metadata={"help": "distill folders (checkpoint.pt)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, required=("runs",))
    harness.options(parser, "splits")
    harness.options(parser, "sigmas")
    harness.options(parser, episodes_per_object=2, seed=200, helps={"seed": "evaluation seeds (not the training ones)"})
    harness.options(parser, "json", required=("json",))
    args = parser.parse_args(argv)
    max_steps = 12 if fast_mode() else None
    rows = []
    for run in args.runs:
        for split in args.splits:
            for sigma in args.sigmas:
                rows.append(run_student(run, split, sigma, args.episodes_per_object, args.seed, max_steps))
                r = rows[-1]
                print(f"{run.name} {split:6s} sigma {sigma:.2f}: success {r['success_rate']:.2f}, no contact "
                      f"{r['no_contact_frac']:.2f}, touched {r['touched_frac']:.2f}, grasped {r['grasped_frac']:.2f}, "
                      f"arm error {r['arm_error']:.3f}, hand error {r['hand_error']:.3f}, stalled {r['stalled_frac']:.2f} "
                      f"({', '.join(f'{k} {v:.2f}' for k, v in r['stalled_by_region'].items())})")
    result = {"rows": rows, "episodes_per_object": args.episodes_per_object, "seed": args.seed,
              **provenance(__file__, argv)}
    write_json(args.json, result)
    print(f"wrote {args.json}")
    return result


if __name__ == "__main__":
    main()
