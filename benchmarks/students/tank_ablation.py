"""Do toilet policies find the lid by the tank? Seen toilets evaluated with and without their tank in the cloud.

    python benchmarks/students/tank_ablation.py --ckpts runs/curriculum/toilet_cloud_student_s0/checkpoint.pt \
        runs/curriculum/toilet_cloud_student_s1/checkpoint.pt --episodes 5 --jobs 2

Why: no toilet policy, student or RL, opens the unseen toilets of template C (tankless, squarish), while the same
policies open unseen toilets of templates A and B (with tanks) as often as seen ones
(``success_by_template.py``). Every seen toilet has a tank. If a policy locates the lid by the tank, the biggest
shape in its cloud, a seen toilet whose tank the camera does not see should fail as C toilets do.

How: each checkpoint is evaluated by ``dexart-lite eval``'s own function (deterministic actions from the true reset,
point and camera noise on, the env seeded once with ``--seed``, rounds of one episode per object) on the seen
toilets twice, with the same seed, so both conditions start from the same object poses and camera perturbations:
``intact`` (the env as it is) and ``no_tank``: before the sensor samples its 512 points, the camera points of the
toilet's body that lie on its tank above the seat are dropped, so the cloud is close to the one a camera would see
of the same toilet with its tank cut off at the seat (the tank's lower part and the back deck below it stay; a
template C toilet has a short deck instead). Tank points are found in the body's root frame from the lid's hinge
frame: behind the hinge (x > hinge x + lid thickness / 2 + 2 mm, the generator puts the tank's front 4 mm behind
the lid's reach) and above the seat (z > hinge z - lid thickness / 2); the lid (label ``functional_part``) and the
robot are never dropped. A template C toilet has nothing there, so ``--split unseen`` checks that the eraser
leaves C toilets' clouds alone. The physics is untouched: the tank still stops the lid past theta_max.

Written to ``benchmarks/results/students/tank_ablation_toilet.json``: per checkpoint and condition the success,
mean highest stage (1 reach, 2 contact, 3 lift) and the mean share of the observed camera points that were
dropped, per template; the command and machine.
"""

from __future__ import annotations

import argparse
import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite import objects as objects_lib
from dexart_lite import pointcloud as pc
from dexart_lite.articulated import PART_LINK
from dexart_lite.rl.evaluate import evaluate as evaluate_policy
from dexart_lite.rl.evaluate import load_policy
from dexart_lite.utils import benchmark_results, check_choice, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

CONDITIONS = ("intact", "no_tank")
TANK_MARGIN = 0.002  # m behind the lid's back face; the tank's front is 4 mm behind it (objects/toilet.py)


def tank_mask(points: np.ndarray, labels: np.ndarray, root_pos, root_quat, hinge_pos, lid_t: float) -> np.ndarray:
    """(M,) bool: the points (M, 3) world frame that lie on a toilet's tank, as defined in the module docstring.
    ``root_pos`` / ``root_quat``: the body's root frame (world); ``hinge_pos``: the lid link's origin (world)."""
    rot = pc.quat_to_matrix(root_quat)  # body -> world
    local = (points - np.asarray(root_pos)) @ rot  # rows R^T p: world -> body frame
    hinge = (np.asarray(hinge_pos) - np.asarray(root_pos)) @ rot
    return ((labels == pc.LABELS.index("object")) & (local[:, 0] > hinge[0] + lid_t / 2 + TANK_MARGIN)
            & (local[:, 2] > hinge[2] - lid_t / 2))


def erase_tank(env, prob: float = 1.0, seed: int = 0) -> list[float]:
    """Make ``env`` (a toilet env, unwrapped) drop its tank's points before sampling, in every episode (``prob`` 1)
    or in each episode with probability ``prob``, drawn at the episode's reset from a generator of its own
    (``seed``), so the env's RNG stream is untouched; returns the list that collects, per observation of an episode
    without its tank, the share of labelled camera points dropped."""
    sensor, objects, sim = env.sensor, env.objects, env.sim
    original, original_reset = sensor.visible_points, sensor.reset
    dropped: list[float] = []
    draw, hidden = np.random.default_rng(seed), [True]

    def reset(rng):
        original_reset(rng)
        hidden[0] = prob >= 1.0 or bool(draw.random() < prob)

    def visible_points(depth=None, seg=None):
        points, labels = original(depth, seg)  # robot-base frame
        if not hidden[0]:
            return points, labels
        world = points + sensor.robot_base
        root_pos, root_quat = sim.base_frame(objects.body)
        hinge_pos, _ = sim.link_frames(objects.body, [PART_LINK])  # the lid's frame sits on the hinge
        keep = ~tank_mask(world, labels, root_pos, root_quat, hinge_pos[0], objects.active.params["lid_t"])
        dropped.append(float(1.0 - keep.mean()) if len(keep) else 0.0)
        return points[keep], labels[keep]

    sensor.visible_points, sensor.reset = visible_points, reset
    return dropped


def evaluate(ckpt: str, split: str, condition: str, episodes: int, seed: int) -> dict:
    """One checkpoint on one split under one condition (``rl.evaluate.evaluate``, the eraser installed through its
    ``prepare_env`` hook for ``no_tank``); success and stage overall and per template."""
    actor_critic, cfg, env_kwargs = load_policy(ckpt)
    if cfg["task"] != "toilet":
        raise ValueError(f"{ckpt} is a {cfg['task']} policy; this ablation needs a toilet policy")
    erasers: list[list[float]] = []  # the eraser's record of dropped shares, once installed
    prepare = (lambda env: erasers.append(erase_tank(env))) if condition == "no_tank" else None
    result = evaluate_policy(actor_critic, "toilet", split, episodes, seed, env_kwargs, prepare_env=prepare)
    dropped = erasers[0] if erasers else []
    template = {info.name: info.template for info in objects_lib.list_objects("toilet", split)}
    by_template: dict[str, dict] = {}
    for t in sorted(set(template.values())):  # every object has the same episodes: plain means over objects
        objs = [r for name, r in result["objects"].items() if template[name] == t]
        by_template[t] = {"objects": len(objs), "episodes": sum(r["episodes"] for r in objs),
                          "success": float(np.mean([r["success_rate"] for r in objs])),
                          "mean_max_stage": float(np.mean([r["mean_max_stage"] for r in objs]))}
    return {"checkpoint": ckpt, "split": split, "condition": condition, "frames": cfg["frames"],
            "success": result["success_rate"], "mean_max_stage": result["mean_max_stage"],
            "dropped_share": float(np.mean(dropped)) if dropped else 0.0, "templates": by_template}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    ckpts: list[str] = field(default_factory=list, metadata={"help": "toilet checkpoints (distill or PPO)"})
    episodes: int = field(default=5, metadata={"min": 1, "help": "episodes per object and condition"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, required=("ckpts",))
    harness.options(parser, "split")
    harness.options(parser, "jobs", seed=1000, json=benchmark_results(__file__) / "tank_ablation_toilet.json",
                    helps={"seed": "env seed (both conditions)"})
    args = parser.parse_args(argv)
    check_choice("split", args.split, ("seen", "unseen"))
    if args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    for ckpt in args.ckpts:
        if not Path(ckpt).is_file():
            raise FileNotFoundError(f"no checkpoint at {ckpt}")
    grid = [{"ckpt": c, "condition": cond} for c in args.ckpts for cond in CONDITIONS]
    job = functools.partial(evaluate, split=args.split, episodes=args.episodes, seed=args.seed)
    results = list(harness.each(job, grid, jobs=args.jobs, desc="evaluations"))
    print("| checkpoint | condition | dropped | success | max stage | " +
          " | ".join(f"template {t}" for t in results[0]["templates"]) + " |")
    for r in results:
        print(f"| {r['checkpoint']} | {r['condition']} | {r['dropped_share']:.2f} | {r['success']:.2f} | "
              f"{r['mean_max_stage']:.2f} | " + " | ".join(f"{v['success']:.2f} (stage {v['mean_max_stage']:.2f})"
                                                         for v in r["templates"].values()) + " |")
    out = {"split": args.split, "episodes_per_object": args.episodes, "seed": args.seed, "results": results,
           **provenance(__file__, argv)}
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return out


if __name__ == "__main__":
    main()
