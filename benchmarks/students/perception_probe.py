"""Diagnostic: how precisely can a PointNet read the object's state from the observed cloud? (perception)

    python benchmarks/students/perception_probe.py --task laptop --json benchmarks/results/students/perception_probe_laptop.json

The point-cloud students of ``dexart-lite distill`` never open a laptop, while an MLP *given* the lid's
state does (``benchmarks/students/state_student.py``). This probe measures the perception half on its own: the
scripted expert (with executed-action noise ``--noise``, so the hand is where a student's would be)
runs on the seen objects (training data) and, with other seeds, on seen and unseen objects (test
data); a PointNet with a small MLP head is fitted to the expert's privileged view of the object
(``experts.Solver.privileged``: part position and orientation, joint angle and target, extent, grasp
point; targets standardised) from the observation's cloud of 512 observed + 96 imagined points, and
the test error is reported in physical units (cm, rad) next to the spread of each quantity.

Variants (``--variants``), each trained with the same data, epochs and seed:

* ``dexart``: DexArt's input, xyz in the robot-base frame (m), as the actor-critic sees it.
* ``scaled``: xyz centred on the crop box and divided by ``SCALE``, so that the features of the first
  layer start at the size of a centimetre instead of a tenth of it.
* ``labels``: ``scaled`` plus each point's segmentation one-hot (functional part, rest of the object,
  hand, arm) as 4 more input channels (DexArt's ``pc_seg`` option has such channels).
* ``scaled-medium``, ``labels-medium``: the same with the medium PointNet.

One seed (``--seed``); the JSON records the command, the machine and the wall time of each variant.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make
from dexart_lite.demos import episode_list
from dexart_lite.models.pointnet import PointNetEncoder
from dexart_lite.pointcloud import LABELS
from dexart_lite.rollout import noisy, run_episodes
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.registration import privileged_slices
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

VARIANTS = ("dexart", "scaled", "labels", "scaled-medium", "labels-medium")
SCALE = 0.2  # m: ``scaled`` divides the centred coordinates by this
# Groups of the 20 privileged entries (Solver.privileged, registration.EXPERT_PRIVILEGED) and the unit each
# error is reported in.
_AT = privileged_slices()
GROUPS = {"part_position_cm": (_AT["part_pos"], 100.0), "part_rotation": (_AT["part_rot"], 1.0),
          "joint_angle_rad": (_AT["joint"], 1.0), "joint_target_rad": (_AT["joint_target"], 1.0),
          "extent_cm": (_AT["part_bounds"], 100.0), "grasp_point_cm": (_AT["grasp_pos"], 100.0)}


def collect(task: str, split: str, episodes_per_object: int, noise: float, seed: int,
            max_steps: int | None) -> dict[str, torch.Tensor]:
    """Noisy-expert rollouts: per step the observed cloud (608, 3), its labels (608,) and the expert's
    privileged view of the state that cloud shows (20,)."""
    env = make(task, split=split, max_episode_steps=max_steps)
    expert = ScriptedPolicy(env)
    rows: dict[str, list] = {"points": [], "labels": [], "privileged": []}

    def record(obs, action, reward, next_obs, info, t):  # the state after the step is the one next_obs shows
        rows["points"].append(np.asarray(next_obs["point_cloud"], np.float32))
        rows["labels"].append(np.asarray(info["point_labels"], np.int64))
        rows["privileged"].append(expert.solver.privileged(env.unwrapped.state))

    episodes = episode_list(env.unwrapped.objects.names, episodes_per_object, np.random.default_rng([seed, 7]))
    run_episodes(noisy(expert, noise, np.random.default_rng([seed, 8])), env, episodes, on_step=record,
                 progress=not fast_mode())
    env.close()
    return {k: torch.as_tensor(np.stack(v)) for k, v in rows.items()}


def inputs(variant: str, data: dict[str, torch.Tensor], centre: torch.Tensor) -> torch.Tensor:
    """The encoder's input for ``variant``: (S, 608, 3) or (S, 608, 7)."""
    if variant == "dexart":
        return data["points"]
    scaled = (data["points"] - centre) / SCALE
    if variant.startswith("labels"):
        onehot = torch.nn.functional.one_hot(data["labels"].clamp_min(0), len(LABELS)).float()
        return torch.cat([scaled, onehot], dim=-1)
    return scaled


def probe(variant: str, train: dict, tests: dict[str, dict], centre: torch.Tensor, epochs: int, seed: int) -> dict:
    """Fit encoder + head to the standardised privileged state; test RMSE per group, physical units."""
    torch.manual_seed(seed)
    x = inputs(variant, train, centre)
    encoder = PointNetEncoder("medium" if variant.endswith("medium") else "small", in_channels=x.shape[-1])
    head = torch.nn.Sequential(torch.nn.Linear(encoder.feature_dim, 256), torch.nn.ReLU(), torch.nn.Linear(256, 20))
    optimizer = torch.optim.Adam([*encoder.parameters(), *head.parameters()], lr=1e-3)
    y = train["privileged"]
    mean, std = y.mean(0), y.std(0).clamp_min(1e-3)
    start, losses = time.perf_counter(), []
    for _ in range(epochs):
        total = 0.0
        for idx in torch.randperm(len(x)).split(256):
            loss = (head(encoder(x[idx])) - (y[idx] - mean) / std).pow(2).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(x))
    result = {"train_loss": losses, "wall_time_s": time.perf_counter() - start}
    with torch.no_grad():
        for name, data in tests.items():
            xt = inputs(variant, data, centre)
            err = torch.cat([head(encoder(chunk)) for chunk in xt.split(512)]) * std + mean - data["privileged"]
            result[name] = {group: float(err[:, s].pow(2).mean().sqrt()) * unit for group, (s, unit) in GROUPS.items()}
    return result


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    test_episodes_per_object: int = field(default=1, metadata={"min": 1, "help": "test episodes per object and split"})
    noise: float = field(default=0.3, metadata={"min": 0.0, "help": "std of the expert's executed-action noise"})
    variants: list[str] = field(default_factory=lambda: list(VARIANTS),
                                metadata={"choices": list(VARIANTS), "help": "the probe variants, one probe each"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", "episodes_per_object",
                    helps={"episodes_per_object": "training episodes per seen object"})
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, epochs=20)
    harness.options(parser, "seed", "json")
    args = parser.parse_args(argv)
    torch.set_num_threads(2)
    max_steps = 30 if fast_mode() else None  # fast mode: a smoke run of the script, not evidence
    if fast_mode():
        args.episodes_per_object, args.test_episodes_per_object, args.epochs = 1, 1, 1
        args.variants = args.variants[:2]

    start = time.perf_counter()
    train = collect(args.task, "seen", args.episodes_per_object, args.noise, args.seed, max_steps)
    tests = {split: collect(args.task, split, args.test_episodes_per_object, args.noise, args.seed + 1000 + i,
                            max_steps) for i, split in enumerate(("seen", "unseen"))}
    collect_s = time.perf_counter() - start
    centre = train["points"].reshape(-1, 3).mean(0)
    spread = {split: {group: float(d["privileged"][:, s].std(0).pow(2).mean().sqrt()) * unit
                      for group, (s, unit) in GROUPS.items()} for split, d in tests.items()}
    results = {}
    for variant in args.variants:
        results[variant] = probe(variant, train, tests, centre, args.epochs, args.seed)
        print(f"{variant}: " + ", ".join(f"{g} {results[variant]['unseen'][g]:.2f}" for g in GROUPS), flush=True)

    print(f"\nTest RMSE ({args.task}, unseen objects; in brackets: the spread (std) of the quantity)")
    print("| variant | " + " | ".join(f"{g} ({spread['unseen'][g]:.2f})" for g in GROUPS) + " | train loss |")
    print("|---|" + "---|" * (len(GROUPS) + 1))
    for variant, r in results.items():
        print(f"| {variant} | " + " | ".join(f"{r['unseen'][g]:.2f} / seen {r['seen'][g]:.2f}" for g in GROUPS)
              + f" | {r['train_loss'][-1]:.3f} |")
    out = {"task": args.task, "noise": args.noise, "epochs": args.epochs, "seed": args.seed,
           "train_samples": len(train["points"]), "test_samples": {k: len(v["points"]) for k, v in tests.items()},
           "spread": spread, "results": results, "collect_s": collect_s,
           "wall_time_s": time.perf_counter() - start, **provenance(__file__, argv), "runs_alongside": "nothing (ran alone)"}
    if args.json:
        write_json(args.json, out)
    return out


if __name__ == "__main__":
    main()
