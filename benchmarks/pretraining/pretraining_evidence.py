"""The evidence for segmentation pretraining: segmentation mIoU per task, PPO from segmentation pretraining vs.
from scratch, and the PPO-fine-tuned encoder put back under the segmentation head.

    # 1. per task: DAM data (seen + unseen), segmentation pretraining, mIoU on seen / unseen objects
    python benchmarks/pretraining/pretraining_evidence.py seg --tasks faucet bucket laptop toilet
    # 2. Laptop PPO, pretrained vs. scratch: same frames, same seeds, same settings otherwise
    python benchmarks/pretraining/pretraining_evidence.py ppo --task laptop --frames 100000 --seeds 0
    # 3. the fine-tuned encoder of the pretrained arm under the segmentation head it started with
    python benchmarks/pretraining/pretraining_evidence.py after-ppo --task laptop --seed 0
    # 4. the other methods: cls on the objects-only set, recon and simsiam on Laptop DAM
    python benchmarks/pretraining/pretraining_evidence.py methods --epochs 5

Work files (datasets, runs) go to ``--root`` (default ``runs/pretrain``, not committed); the
results (JSON, markdown tables, PNGs) to ``--results`` (default ``benchmarks/results/pretraining``).
Steps that find their output already present are skipped, so an interrupted run can be restarted.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import torch

from dexart_lite.models.pointnet import PointNetEncoder, load_encoder
from dexart_lite.pretrain import data as datasets
from dexart_lite.pretrain import train as pretrain
from dexart_lite.pretrain.figures import plot_segmentation
from dexart_lite.cli import add_config_arguments
from dexart_lite.rl.ppo import PRESETS, PPOConfig
from dexart_lite.study import run_arm
from dexart_lite.utils import benchmark_results, provenance, save_figure, sibling_script

harness = sibling_script(__file__, "_harness")

CLASS_WEIGHTS = {"bucket": "3,1,1,1"}  # DexArt's segmentation weights (functional part up-weighted)
FIGURE_CLOUDS = 2  # per split in the true-vs-predicted pictures


def dataset_dir(root: Path, task: str) -> Path:
    return root / "data" / f"dam_{task}"


def seg_dir(root: Path, task: str) -> Path:
    return root / f"seg_{task}"


def segmentation_figure(encoder, head, data_root: Path, path: Path, title: str) -> Path:
    """True vs. predicted labels of ``FIGURE_CLOUDS`` validation (seen) and test (unseen) clouds."""
    clouds, true, pred, titles = [], [], [], []
    for part, split in (("val", "seen"), ("test", "unseen")):
        data = datasets.load_part(data_root, part)
        picks = torch.linspace(0, len(data) - 1, FIGURE_CLOUDS).round().long()  # spread over the objects
        with torch.no_grad():
            labels = pretrain.segment_logits(encoder, head, data.points[picks]).argmax(-1)
        for i, k in enumerate(picks):
            clouds.append(data.points[k])
            true.append(data.labels[k])
            pred.append(labels[i])
            titles.append(f"{title}: {split} {data.objects[int(data.object_index[k])]['name']}")
    plot_segmentation(clouds, true, pred, titles, path=path)
    return path


def run_seg(args) -> int:
    rows = {}
    results = args.results / "seg_miou.json"
    if results.exists():
        rows = json.loads(results.read_text())["tasks"]
    for task in args.tasks:
        data_root = dataset_dir(args.root, task)
        if not (data_root / "unseen" / datasets.MANIFEST).exists():
            datasets.generate_dam(datasets.DamConfig(task=task, split="all", samples_per_object=args.samples_per_object,
                                                     out=str(data_root), seed=args.seed))
        out = seg_dir(args.root, task)
        if not (out / "metrics.json").exists():
            pretrain.train(pretrain.PretrainConfig(method="seg", data=str(data_root), out=str(out), epochs=args.epochs,
                                                   class_weights=CLASS_WEIGHTS.get(task), seed=args.seed))
        metrics = json.loads((out / "metrics.json").read_text())
        manifests = [datasets.read_manifest(data_root / s) for s in ("seen", "unseen")]
        rows[task] = {
            "miou_seen": metrics["val"]["miou"], "miou_unseen": metrics["test"]["miou"],
            "iou_seen": metrics["val"]["iou"], "iou_unseen": metrics["test"]["iou"],
            "clouds": {p: e["count"] for m in manifests for p, e in m["parts"].items()},
            "class_weights": metrics["config"]["class_weights"], "epochs": metrics["epochs"],
            "seconds_per_epoch": round(metrics["seconds_per_epoch"], 1),
            "pretrain_minutes": round(metrics["wall_seconds"] / 60, 1),
            "data_minutes": round(sum(m["seconds"] for m in manifests) / 60, 1),
            "ms_per_cloud": [m["ms_per_sample"] for m in manifests]}
        encoder = load_encoder(out / "encoder.pt")
        _, head = pretrain.load_head(out / "head.pt")
        segmentation_figure(encoder, head, data_root, args.results / f"seg_{task}.png", task)
        args.results.mkdir(parents=True, exist_ok=True)
        results.write_text(json.dumps({**args.provenance, "samples_per_object": args.samples_per_object,
                                       "tasks": rows}, indent=2) + "\n")
        print(f"{task}: mIoU seen {rows[task]['miou_seen']:.3f}, unseen {rows[task]['miou_unseen']:.3f}", flush=True)
    lines = ["| task | mIoU seen (val) | mIoU unseen (test) | IoU functional part seen / unseen | train clouds | "
             "epochs | data min | pretrain min |", "|---|---|---|---|---|---|---|---|"]
    for task, r in rows.items():
        lines.append(f"| {task} | {r['miou_seen']:.3f} | {r['miou_unseen']:.3f} | "
                     f"{r['iou_seen']['functional_part']:.3f} / {r['iou_unseen']['functional_part']:.3f} | "
                     f"{r['clouds']['train']} | {r['epochs']} | {r['data_minutes']} | {r['pretrain_minutes']} |")
    (args.results / "seg_miou.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def ppo_dir(root: Path, arm: str, task: str, seed: int) -> Path:
    return root / f"ppo_{task}_{arm}_seed{seed}"


def run_ppo(args) -> int:
    from dexart_lite.rl import ppo

    encoder = seg_dir(args.root, args.task) / "encoder.pt"
    if not encoder.exists():
        raise FileNotFoundError(f"{encoder} missing: run the `seg` step for {args.task} first")
    arms = {"scratch": None, "pretrained": str(encoder)}
    summary = {"task": args.task, "frames": args.frames, "seeds": args.seeds, "preset": args.preset,
               "eval_episodes_per_object": args.eval_episodes, **args.provenance, "arms": {}}
    grid = [{"arm": arm, "seed": seed, "cfg": ppo.preset(args.preset, task=args.task, frames=args.frames, seed=seed,
                                                         out=str(ppo_dir(args.root, arm, args.task, seed)),
                                                         pretrained=pretrained, eval_episodes=args.eval_episodes,
                                                         workers=args.workers)}
            for arm, pretrained in arms.items() for seed in args.seeds]
    rows = list(harness.each(ppo_run, grid, desc="PPO runs"))
    for arm in arms:
        runs = [row for params, row in zip(grid, rows) if params["arm"] == arm]
        summary["arms"][arm] = {"runs": runs, **{f"success_{split}": sum(r[f"success_{split}"] for r in runs) / len(runs)
                                                 for split in ("seen", "unseen")}}
    args.results.mkdir(parents=True, exist_ok=True)
    name = f"ppo_{args.task}_pretrained_vs_scratch"
    (args.results / f"{name}.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_ppo(summary, args.results / f"{name}.png")
    for arm, r in summary["arms"].items():
        print(f"{arm}: success seen {r['success_seen']:.2f}, unseen {r['success_unseen']:.2f}")
    return 0


def ppo_run(arm: str, seed: int, cfg) -> dict:
    """One PPO run through ``study.run_arm`` (trained, continued from its checkpoint, or read back)."""
    record = run_arm(cfg)
    print(f"{arm} seed {seed}: {record['wall_time_s'] / 60:.1f} min", flush=True)
    return {"seed": seed, "out": cfg.out, "success_seen": record["seen_success"], "success_unseen": record["unseen_success"],
            "wall_minutes": round(record["wall_time_s"] / 60, 1),
            "curve": [{k: h[k] for k in ("frames", "episode_return", "success_rate", "progress")}
                      for h in record["history"]]}


def plot_ppo(summary: dict, path: Path) -> Path:
    """Training-episode return and progress against frames, one line per arm and seed."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 3.4))
    axes = fig.subplots(1, 3)
    colours = {"scratch": "tab:gray", "pretrained": "tab:red"}
    for arm, r in summary["arms"].items():
        for run in r["runs"]:
            frames = [h["frames"] for h in run["curve"]]
            label = f"{arm} (seed {run['seed']})"
            for ax, key in zip(axes, ("episode_return", "progress", "success_rate")):
                ax.plot(frames, [h[key] for h in run["curve"]], marker=".", color=colours[arm], label=label)
    for ax, title in zip(axes, ("training episode return", "mean task progress", "training success rate")):
        ax.set(xlabel="env frames", title=title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"PPO {summary['task']}: segmentation-pretrained vs. scratch encoder, {summary['preset']} preset")
    return save_figure(fig, path)


def run_after_ppo(args) -> int:
    from dexart_lite.models.actor_critic import encoder_of
    from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint

    data_root, seg = dataset_dir(args.root, args.task), seg_dir(args.root, args.task)
    _, head = pretrain.load_head(seg / "head.pt")
    encoders = {"after segmentation pretraining": load_encoder(seg / "encoder.pt")}
    for arm in ("pretrained", "scratch"):
        checkpoint = ppo_dir(args.root, arm, args.task, args.seed) / "checkpoint.pt"
        if checkpoint.exists():
            payload = load_checkpoint(checkpoint)
            encoders[f"after PPO ({arm} arm, {payload['frames']:,} frames)"] = encoder_of(
                actor_critic_from_checkpoint(payload, checkpoint))
    result = {"task": args.task, "head": str(seg / "head.pt"), "encoders": {}}
    for name, encoder in encoders.items():
        encoder.eval()
        metrics = {part: pretrain.evaluate("seg", encoder, head, datasets.load_part(data_root, part))
                   for part in ("val", "test")}
        result["encoders"][name] = {"miou_seen": metrics["val"]["miou"], "miou_unseen": metrics["test"]["miou"],
                                    "iou_seen": metrics["val"]["iou"], "iou_unseen": metrics["test"]["iou"]}
        print(f"{name}: mIoU seen {metrics['val']['miou']:.3f}, unseen {metrics['test']['miou']:.3f}", flush=True)
    finetuned = next((e for n, e in encoders.items() if "pretrained arm" in n), None)
    if finetuned is not None:
        segmentation_figure(finetuned, head, data_root, args.results / f"seg_{args.task}_after_ppo.png",
                            f"{args.task} after PPO")
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / f"seg_{args.task}_after_ppo.json").write_text(json.dumps(result, indent=2) + "\n")
    return 0


def run_methods(args) -> int:
    """cls on the objects-only set; recon and simsiam on the task's DAM set (made by the ``seg`` step)."""
    objects_root = args.root / "data" / "objects"
    if not (objects_root / "unseen" / datasets.MANIFEST).exists():
        datasets.generate_objects(datasets.ObjectsConfig(samples_per_object=args.object_samples, out=str(objects_root),
                                                         seed=args.seed))
    dam = dataset_dir(args.root, args.task)
    if not (dam / "unseen" / datasets.MANIFEST).exists():
        raise FileNotFoundError(f"{dam} missing: run the `seg` step for {args.task} first")
    results = {}
    for method, data in (("cls", objects_root), ("simsiam", objects_root), ("recon", dam), ("simsiam", dam)):
        name = f"{method}_{'objects' if data == objects_root else args.task}"
        out = args.root / name
        if not (out / "metrics.json").exists():
            pretrain.train(pretrain.PretrainConfig(method=method, data=str(data), out=str(out), epochs=args.epochs,
                                                   seed=args.seed))
        metrics = json.loads((out / "metrics.json").read_text())
        results[name] = {k: metrics[k] for k in ("method", "kind", "train_clouds", "epochs", "seconds_per_epoch",
                                                 "wall_seconds", "val", "test") if k in metrics}
        if method == "simsiam":  # the k-NN probe with an untrained encoder: what the training adds
            results[name]["knn_accuracy_untrained_val"] = untrained_knn(data, args.seed)
        key = pretrain.MAIN_METRIC[method]
        print(f"{name}: val {key} {metrics['val'].get(key)}, test {metrics.get('test', {}).get(key)}", flush=True)
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / "methods.json").write_text(json.dumps({**args.provenance, "runs": results}, indent=2) + "\n")
    return 0


def untrained_knn(data_root: Path, seed: int) -> float:
    """SimSiam's validation k-NN accuracy with a freshly initialised encoder (same bank and target)."""
    torch.manual_seed(seed)
    encoder = PointNetEncoder("small")
    train_set, val_set = datasets.load_part(data_root, "train"), datasets.load_part(data_root, "val")
    subset = train_set.subset(torch.randperm(len(train_set), generator=torch.Generator().manual_seed(0))[:pretrain.KNN_BANK])
    by_category = pretrain.knn_target(train_set) == "category"
    bank = (pretrain.encode_all(encoder, subset), subset.category if by_category else subset.object_index)
    target = val_set.category if by_category else val_set.object_index
    return pretrain.knn_accuracy(*bank, pretrain.encode_all(encoder, val_set), target)


@dataclass
class Flags:
    """This script's own flags, each on the step that takes it; the shared ones come from the harness."""

    root: Path = field(default=Path("runs/pretrain"), metadata={"help": "datasets and runs"})
    preset: str = field(default="cpu", metadata={"choices": list(PRESETS), "help": "the PPO preset (ppo step)"})
    object_samples: int = field(default=datasets.DEFAULT_OBJECT_SAMPLES, metadata={
        "min": 1, "help": "clouds per generated object for the methods' pretraining data"})


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False, names=["root"])
    harness.options(parser, results=benchmark_results(__file__))
    sub = parser.add_subparsers(dest="step", required=True)
    seg = sub.add_parser("seg", help="DAM data + segmentation pretraining + mIoU per task")
    harness.options(seg, "tasks")
    add_config_arguments(seg, datasets.DamConfig, names=["samples_per_object"], overrides=False)
    harness.options(seg, "seed", epochs=10)
    ppo_parser = sub.add_parser("ppo", help="PPO from the segmentation encoder vs. from scratch")
    harness.options(ppo_parser, "task", frames=100_000, seeds=[0], eval_episodes=4)
    add_config_arguments(ppo_parser, PPOConfig, names=["workers"], defaults={"workers": 2}, overrides=False)
    add_config_arguments(ppo_parser, Flags, overrides=False, names=["preset"])
    after = sub.add_parser("after-ppo", help="the PPO-fine-tuned encoder under the segmentation head")
    harness.options(after, "task", "seed")
    methods = sub.add_parser("methods", help="cls, recon and simsiam runs with their metrics")
    harness.options(methods, "task", "seed", epochs=5)
    add_config_arguments(methods, Flags, overrides=False, names=["object_samples"])
    args = parser.parse_args(argv)
    args.provenance = provenance(__file__, argv)  # recorded in every JSON a step writes
    return {"seg": run_seg, "ppo": run_ppo, "after-ppo": run_after_ppo, "methods": run_methods}[args.step](args)


if __name__ == "__main__":
    sys.exit(main())
