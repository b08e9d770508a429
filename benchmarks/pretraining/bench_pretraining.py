"""Pretraining cost: DAM generation per task (ms per cloud) and seconds per epoch per method.

* ``dam_ms_per_cloud``: ``generate_dam`` on ``--objects`` seen objects of each task,
  ``--clouds`` clouds each (env step with rendering, random action and joint state, shard writing);
  the minutes for one task at the default ``--samples-per-object`` follow from it (seen + unseen).
* ``seconds_per_epoch``: one epoch of ``dexart_lite.pretrain.train`` per method (training steps
  only, no evaluation) on a fixed small dataset: ``--train-clouds`` laptop DAM clouds for seg,
  recon and simsiam, as many objects-only clouds for cls; reported per 1,000 clouds as well.

    python benchmarks/pretraining/bench_pretraining.py --json benchmarks/results/pretraining/bench_pretraining.json
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch

import dexart_lite
from dexart_lite.cli import add_config_arguments
from dexart_lite.models.pointnet import PointNetEncoder
from dexart_lite.objects import CATEGORIES, list_objects
from dexart_lite.pretrain import data as datasets
from dexart_lite.pretrain import train as pretrain
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")


def dam_cost(task: str, objects: int, clouds: int, root: Path) -> float:
    """ms per DAM cloud on ``objects`` seen objects of ``task``."""
    names = [o.name for o in list_objects(task, "seen")[:objects]]
    cfg = datasets.DamConfig(task=task, split="seen", samples_per_object=clouds, out=str(root / f"dam_{task}"),
                             objects=",".join(names), val_fraction=0.0, progress=False)
    start = time.perf_counter()
    datasets.generate_dam(cfg)
    return 1000 * (time.perf_counter() - start) / (objects * clouds)


def epoch_seconds(method: str, data: datasets.PointCloudSet, encoder_size: str = "small") -> float:
    """Seconds of one training epoch of ``method`` on ``data`` (after one warm-up step)."""
    torch.manual_seed(0)
    cfg = pretrain.PretrainConfig(method=method, encoder=encoder_size)
    encoder, head = PointNetEncoder(encoder_size), pretrain.make_head(cfg, data.num_classes)
    optimizer = torch.optim.Adam([*encoder.parameters(), *head.parameters()], lr=cfg.lr)
    generator = torch.Generator().manual_seed(0)
    size = pretrain.BATCH_SIZE[method]

    def step(batch) -> None:
        loss, _ = pretrain.batch_loss(method, encoder, head, batch, generator=generator)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    step(next(pretrain.batches(data, size)))
    start = time.perf_counter()
    for batch in pretrain.batches(data, size, torch.randperm(len(data), generator=generator)):
        step(batch)
    return time.perf_counter() - start


@dataclass
class Flags:
    """This script's own flags; the DAM's come from DamConfig."""

    objects: int = field(default=2, metadata={"min": 1, "help": "seen objects per task for the DAM timing"})
    clouds: int = field(default=150, metadata={"min": 1, "help": "DAM clouds per object for the timing"})
    train_clouds: int = field(default=1000, metadata={"min": 1, "help": "clouds in the fixed training set"})


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "tasks", helps={"tasks": "tasks whose DAM generation is timed"})
    add_config_arguments(parser, Flags, overrides=False)
    add_config_arguments(parser, datasets.DamConfig, names=["samples_per_object"], overrides=False,
                         helps={"samples_per_object": "DAM size the minutes per task are given for"})
    harness.options(parser, "json", threads=2)
    args = parser.parse_args(argv)
    if fast_mode():  # a smoke run of the script itself, not a measurement
        args.tasks, args.objects, args.clouds, args.train_clouds = ["laptop"], 1, 5, 32
    torch.set_num_threads(args.threads)
    tasks = args.tasks
    results = {**provenance(__file__, argv), "torch": torch.__version__, "dexart_lite": dexart_lite.__version__,
               "threads": args.threads, "dam": {}, "methods": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for task in tasks:
            ms = dam_cost(task, args.objects, args.clouds, root)
            seen, unseen = len(list_objects(task, "seen")), len(list_objects(task, "unseen"))
            minutes = ms * args.samples_per_object * (seen + unseen) / 60_000
            results["dam"][task] = {"ms_per_cloud": round(ms, 2), "objects_seen": seen, "objects_unseen": unseen,
                                    "samples_per_object": args.samples_per_object, "minutes": round(minutes, 1)}
            print(f"DAM {task}: {ms:.1f} ms per cloud -> {minutes:.1f} min for {args.samples_per_object} "
                  f"clouds x {seen + unseen} objects", flush=True)
        per_object = max(1, -(-args.train_clouds // 2))
        datasets.generate_dam(datasets.DamConfig(
            task="laptop", split="seen", samples_per_object=per_object, val_fraction=0.0, out=str(root / "dam"),
            objects=",".join(o.name for o in list_objects("laptop", "seen")[:2]), progress=False))
        per_object = max(1, -(-args.train_clouds // (2 * len(CATEGORIES))))
        datasets.generate_objects(datasets.ObjectsConfig(
            split="seen", samples_per_object=per_object, val_fraction=0.0, out=str(root / "objects"),
            objects=",".join(o.name for c in CATEGORIES for o in list_objects(c, "seen")[:2]), progress=False))
        dam = datasets.load_part(root / "dam", "train")
        objects = datasets.load_part(root / "objects", "train")
        for method in pretrain.METHODS:
            data = objects if method == "cls" else dam
            data = data.subset(torch.arange(min(len(data), args.train_clouds)))
            seconds = epoch_seconds(method, data)
            results["methods"][method] = {"clouds": len(data), "points": data.points.shape[1],
                                          "batch_size": pretrain.BATCH_SIZE[method],
                                          "seconds_per_epoch": round(seconds, 2),
                                          "seconds_per_1000_clouds": round(1000 * seconds / len(data), 2)}
    print(f"\n| method | clouds x points | batch | s / epoch | s / 1000 clouds |\n|---|---|---|---|---|")
    for method, r in results["methods"].items():
        print(f"| {method} | {r['clouds']} x {r['points']} | {r['batch_size']} | {r['seconds_per_epoch']:.1f} | "
              f"{r['seconds_per_1000_clouds']:.1f} |")
    print(f"\n{results['machine']['cpu']}, {results['machine']['cores']} cores, torch {torch.__version__}, "
          f"{args.threads} threads")
    if args.json:
        write_json(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
