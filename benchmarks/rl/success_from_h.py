"""Where does a policy fail? Its success when it takes over from the scripted expert after h steps.

    python benchmarks/rl/success_from_h.py --task bucket --jobs 2 \\
        --policy student_s0=runs/curriculum/bucket_cloud_student_s0/checkpoint.pt \\
        --policy rl_s0=runs/curriculum/bucket_cloud_student_anchored_floor_reverse_s0/checkpoint.pt \\
        --h 0 50 100 125 140 155 170 --json benchmarks/results/rl/bucket_success_from_h.json
    python benchmarks/rl/success_from_h.py --task bucket --jobs 2 --policy expert --noise 0 0.03 0.05 0.1 \\
        --h 0 50 100 125 140 155 --json benchmarks/results/rl/bucket_expert_noise_from_h.json
    python benchmarks/rl/success_from_h.py --task bucket --jobs 2 --policy expert --noise 0.03 0.1 --noise-on arm \\
        --h 0 50 100 125 140 155 --json benchmarks/results/rl/bucket_expert_noise_arm_from_h.json   # and hand

The episodes are the reverse curriculum's demonstrations (``rl/curriculum.find_demos``: ``--demos`` (reset seed,
object) pairs of the seen split that the noise-free expert solves, the ``solve`` order from ``--seed``). For each
policy and each ``h`` every demonstration is replayed: the expert acts ``h`` steps from ``reset(seed)`` (exact replay,
``GuidedStart.start``), then the policy acts, deterministically, to the end of the episode; success counts at any
step after the hand-over. ``expert`` as a policy continues the same expert (its success is 1 from every ``h``: a
check of the replay). A policy that succeeds from late ``h`` and not from early ones has learned the end of the
task and not its beginning; the step where its success falls says which phase it lacks (compare with the expert's
``benchmarks/experts/stage_timeline.py``). ``--noise``: after the hand-over the executed action is the policy's plus
Gaussian noise of that std, clipped to [-1, 1] (``rollout.Noisy``; PPO's exploration, whose actions are drawn around
the mean with the policy's std); the expert with noise says from which step on a task tolerates a learner's
exploration. The noise has its own generator, seeded per ``h``, so policies at the same std meet the same draws.
``--noise-on arm`` / ``hand`` puts it on the palm twist (the first 6 action dimensions) or on the hand's targets only
(``rollout.NOISE_PARTS``): which part of a policy's exploration a task tolerates.

Written to ``--json``: task, demos ([seed, object, first success step]), h, noise, noise_on, policies (label, with
``+noise<std>`` when the std is not 0 and ``@arm`` / ``@hand`` after it with ``--noise-on``: checkpoint, noise, and
per h the success rate and the per-demonstration successes), command, machine; ``--png``: success against h.
"""

from __future__ import annotations

import argparse
import functools
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.curriculum import GuidedStart, find_demos, make_guide
from dexart_lite.rollout import NOISE_PARTS, noisy, run_episodes
from dexart_lite.utils import provenance, save_figure, sibling_script, write_json

harness = sibling_script(__file__, "_harness")


def parse_policy(text: str) -> tuple[str, str]:
    """``label=checkpoint`` (a file or ``zoo:<task>``) or ``expert``."""
    if text == "expert":
        return "expert", "expert"
    from dexart_lite.rl.checkpoint import checkpoint_path

    label, sep, path = text.partition("=")
    if not sep or not label or not checkpoint_path(path).is_file():
        raise argparse.ArgumentTypeError(f"--policy takes label=checkpoint (an existing file or zoo:<task>) or "
                                         f"'expert', got {text!r}")
    return label, str(checkpoint_path(path))


def success_from_h(task: str, label: str, checkpoint: str, demos: list, hs: list[int], noise: float = 0.0,
                   noise_on: str = "all") -> dict:
    """Per ``h``: the success of ``checkpoint``'s deterministic policy (or the expert's, ``checkpoint="expert"``) on
    every demonstration after the expert's first ``h`` steps, with executed-action noise of std ``noise`` on the
    ``noise_on`` part of the action (``rollout.NOISE_PARTS``) after the hand-over."""
    from dexart_lite.envs import make
    from dexart_lite.rl.checkpoint import policy_function
    from dexart_lite.rl.evaluate import load_policy

    torch.set_num_threads(1)
    env_kwargs = {}
    if checkpoint != "expert":
        actor_critic, _, env_kwargs = load_policy(checkpoint)
        policy = policy_function(actor_critic)
    env = GuidedStart(make(task, split="seen", **{"point_noise": True, "camera_noise": True, **env_kwargs}),
                      guide_render=False)
    if checkpoint == "expert":  # it goes on as the instance that led (a new one would start its solver mid-episode)
        expert = make_guide(env.unwrapped, "expert")  # for h = 0, where no guide has acted yet
        policy = lambda obs: (env.guide or expert)(obs)  # noqa: E731
    episodes = [(seed, name) for seed, name, _ in demos]
    rows = {}
    try:
        for h in hs:
            acting = noisy(policy, noise, np.random.default_rng(h), noise_on) if noise > 0 else policy
            successes = [r["success"] for r in run_episodes(acting, HandOver(env, h), episodes)]
            rows[str(h)] = {"success": float(np.mean(successes)), "per_demo": successes}
    finally:
        env.close()
    suffix = "" if noise == 0 else f"+noise{noise:g}" + ("" if noise_on == "all" else f"@{noise_on}")
    return {"label": label + suffix, "checkpoint": checkpoint, "noise": noise, "by_h": rows}


class HandOver(gym.Wrapper):
    """``reset(seed, object)`` is the state the expert leaves after ``h`` steps from that reset (``GuidedStart.start``),
    so the rollout layer's episodes (``rollout.run_episodes``) begin at the hand-over."""

    def __init__(self, env: GuidedStart, h: int):
        super().__init__(env)
        self.h = h

    def reset(self, *, seed=None, options=None):
        return self.env.start(seed, self.h, (options or {}).get("object"))


def plot(result: dict, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label, entry in result["policies"].items():
        ax.plot(result["h"], [entry["by_h"][str(h)]["success"] for h in result["h"]], marker="o", label=label)
    ax.set_xlabel("expert steps before the hand-over (h)")
    ax.set_ylabel("success after the hand-over")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title(f"{result['task']}: {len(result['demos'])} demonstrations (seen objects)")
    ax.legend(fontsize=7)
    save_figure(fig, path)


@dataclass
class Flags:
    """This script's own flags but --policy (repeated, one policy each); the shared ones come from the harness."""

    h: list[int] = field(default_factory=lambda: [0, 50, 100, 125, 140, 155, 170],
                         metadata={"help": "guide steps before the hand-over, one run each"})
    noise: list[float] = field(default_factory=lambda: [0.0], metadata={
        "help": "std(s) of executed-action noise after the hand-over; every policy at each"})
    noise_on: str = field(default="all", metadata={"choices": list(NOISE_PARTS), "help": "the action part the noise "
                          "perturbs: all, arm (palm twist) or hand (joint targets)"})
    demos: int = field(default=11, metadata={"min": 1, "help": "demonstrations (one per seen object by default)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, task="bucket")
    # by hand: repeated (--policy a=x --policy b=y), which a list field's one-or-more values cannot spell
    parser.add_argument("--policy", type=parse_policy, action="append", required=True,
                        help="label=checkpoint, or expert; repeat for several")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "seed", "jobs", "json", "png", helps={"seed": "the demonstrations' solve seed"})
    args = parser.parse_args(argv)
    if min(args.h) < 0:
        raise ValueError(f"--h must be >= 0, got {args.h}")
    if not all(np.isfinite(args.noise)) or min(args.noise) < 0:
        raise ValueError(f"--noise takes stds >= 0, got {args.noise}")
    demos = find_demos(args.task, args.demos, "seen", args.seed)
    if max(args.h) >= min(length for *_, length in demos):
        raise ValueError(f"--h must stay below the demonstrations' first success ({min(l for *_, l in demos)} steps)")
    grid = [{"label": label, "checkpoint": path, "noise": sigma} for label, path in args.policy for sigma in args.noise]
    job = functools.partial(success_from_h, args.task, demos=demos, hs=args.h, noise_on=args.noise_on)
    results = list(harness.each(job, grid, jobs=args.jobs, desc="policies"))
    result = {"task": args.task, "demos": [list(d) for d in demos], "h": args.h, "noise": args.noise,
              "noise_on": args.noise_on,
              "policies": {r["label"]: {"checkpoint": r["checkpoint"], "noise": r["noise"], "by_h": r["by_h"]}
                           for r in results},
              **provenance(__file__, argv)}
    for label, entry in result["policies"].items():
        print(label, " ".join(f"h={h}: {entry['by_h'][str(h)]['success']:.2f}" for h in args.h))
    if args.json:
        write_json(args.json, result)
    if args.png:
        plot(result, args.png)
    return result


if __name__ == "__main__":
    main()
