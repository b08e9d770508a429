"""Where a student's training time goes, and what cuts it: one process, variants side by side.

    python benchmarks/perf/bench_student_training.py --demos runs/distill_laptop_dagger_episodes2x_s0/demos \
        --json benchmarks/results/perf/bench_student_training.json

A distillation run spends most of its wall time in ``distill.train_student`` (on laptops at 2.2x the
episodes: ~620 s of training against ~370 s of collection per seed). This script trains the same
untrained student (``distill.build_student``, the ``DistillConfig`` defaults, one seed) for
``--epochs`` passes over the first ``--samples`` demonstrations once per variant, repeated
``--repeats`` times in turn (A B C A B C ...), and reports samples per second and each variant's
ratio to ``fp32`` measured in the same process:

- ``fp32``: what ``distill`` does today (float32 everywhere, memory-mapped buffer, EMA after every step);
- ``bf16``: the same inside ``torch.autocast("cpu", torch.bfloat16)`` (matrix products in bfloat16,
  weights and optimiser state in float32; a question, not an option of ``distill``); its final loss is reported next to fp32's, from the same
  initial weights and minibatch order, so that a change in what is learned shows;
- ``in_memory``: the samples copied out of the memory map first;
- ``no_ema``: without the moving average of the weights (what the average costs).

With ``--encoders small medium large`` every variant runs once per PointNet size (labels such as
``fp32/large``), all ratios to the first label: the training cost of the encoder study's arms measured
side by side on one machine, where the study's wall times may come from several. With ``--chunks 8 32``
every label runs once per ``pointnet.CHUNK`` (clouds per per-point pass; labels such as ``fp32/chunk8``):
the chunk that keeps a pass in cache depends on the machine's caches and the encoder's widths.

Without ``--demos`` it first collects 2 noisy expert episodes per seen laptop (about 30 s). Timing
varies between machines and with load: run it alone; the JSON names the machine and the threads.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import torch

from dexart_lite.cli import add_config_arguments
from dexart_lite.demos import collect_demos, load_demos, read_manifest
from dexart_lite.imitation.distill import DistillConfig, build_student, train_student
from dexart_lite.models import pointnet
from dexart_lite.models.pointnet import ENCODER_SIZES
from dexart_lite.rl.env import torch_threads
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

VARIANTS = ("fp32", "bf16", "in_memory", "no_ema")


def train_once(variant: str, cfg: DistillConfig, dims: dict, demos, data, epochs: int) -> dict:
    """Build the student of ``cfg`` (its seed, its encoder) and train it ``epochs`` passes over ``data`` as
    ``variant`` says."""
    torch.manual_seed(cfg.seed)
    actor_critic, ema, aux_head = build_student(cfg, dims, demos)
    if variant == "in_memory":
        data = data.clone()  # a TensorDict in RAM instead of memory-mapped files
    autocast = torch.autocast("cpu", dtype=torch.bfloat16) if variant == "bf16" else nullcontext()
    start = time.perf_counter()
    with autocast:
        losses = train_student(actor_critic, data, cfg, epochs, aux_head, None if variant == "no_ema" else ema)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "samples_per_s": epochs * data.batch_size[0] / seconds, "loss_last_epoch": losses[-1]}


@dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    demos: Path | None = field(default=None, metadata={"help": "a demonstrations folder (None: collect a small one)"})
    samples: int = field(default=4096, metadata={"min": 1, "help": "train on the first SAMPLES demonstrations"})
    repeats: int = field(default=3, metadata={"min": 1, "help": "rounds of every variant in turn (A B C A B C ...)"})
    variants: list[str] = field(default_factory=lambda: list(VARIANTS),
                                metadata={"choices": list(VARIANTS), "help": "the training variants timed"})
    encoders: list[str] = field(default_factory=lambda: ["small"], metadata={
        "choices": list(ENCODER_SIZES), "help": "PointNet sizes; with more than one, every variant runs once per size"})
    chunks: list[int] = field(default_factory=lambda: [pointnet.CHUNK], metadata={
        "min": 1, "help": "clouds per per-point pass (pointnet.CHUNK); with more than one, every label runs once per "
                          "chunk"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, epochs=2)
    harness.options(parser, "threads", "json", helps={"json": "where to write the results (default: print only)"})
    args = parser.parse_args(argv)
    if fast_mode():  # a smoke run of the script itself, not evidence
        args.samples, args.epochs, args.repeats = min(args.samples, 64), 1, 1

    with tempfile.TemporaryDirectory() as tmp:
        demo_path = args.demos
        if demo_path is None:
            demo_path = Path(tmp) / "demos"
            collect_demos("laptop", "seen", 1 if fast_mode() else 2, 0.15, 0, demo_path,
                          num_points=32 if fast_mode() else 512, max_episode_steps=10 if fast_mode() else None,
                          object_names=["laptop_11cbb00f39"] if fast_mode() else None)
        manifest = read_manifest(demo_path)
        demos = load_demos(demo_path)
        data = demos[: min(args.samples, manifest["samples"])]
        configs = {encoder: DistillConfig(task=manifest["task"], encoder=encoder, progress=False)
                   for encoder in args.encoders}
        cfg = configs[args.encoders[0]]
        dims = {"num_points": manifest["cloud_points"], "state_dim": manifest["state_dim"],
                "action_dim": data["expert_action"].shape[-1], "head": cfg.head_widths(), "normalize": cfg.normalize}
        threads = args.threads or torch.get_num_threads()
        # label -> (variant, encoder, chunk): "fp32" with one encoder and chunk, "fp32/large/chunk8" with several
        labels = {}
        for e in args.encoders:
            for v in args.variants:
                for c in args.chunks:
                    parts = [v] + ([e] if len(args.encoders) > 1 else []) + ([f"chunk{c}"] if len(args.chunks) > 1 else [])
                    label = "/".join(parts)
                    labels[label] = (v, e, c)
        runs: dict[str, list[dict]] = {label: [] for label in labels}
        default_chunk = pointnet.CHUNK
        with torch_threads(threads):
            for repeat in range(args.repeats):
                for label, (variant, encoder, chunk) in labels.items():
                    pointnet.CHUNK = chunk
                    try:
                        runs[label].append(train_once(variant, configs[encoder], dims, demos, data, args.epochs))
                    finally:
                        pointnet.CHUNK = default_chunk
                    print(f"repeat {repeat} {label:16s} {runs[label][-1]['samples_per_s']:7.0f} samples/s, "
                          f"last loss {runs[label][-1]['loss_last_epoch']:.4f}")

    best = {label: max(r["samples_per_s"] for r in rs) for label, rs in runs.items()}
    first = next(iter(best))
    result = {
        "samples": data.batch_size[0], "epochs": args.epochs, "repeats": args.repeats, "threads": threads,
        "batch_size": cfg.batch_size, "encoder": cfg.encoder, "encoders": args.encoders,
        "chunks": args.chunks,
        "cloud_points": manifest["cloud_points"], "samples_per_s_best": best,
        "ratio_to_fp32": {v: best[v] / best["fp32"] for v in best} if "fp32" in best else None,
        "ratio_to_first": {label: best[label] / best[first] for label in best}, "first": first,
        "loss_last_epoch": {v: rs[0]["loss_last_epoch"] for v, rs in runs.items()},
        "runs": runs, **provenance(__file__, argv), "torch": torch.__version__,
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
    }
    for label in best:
        print(f"{label:16s} {best[label]:7.0f} samples/s (best of {args.repeats}), "
              f"x{result['ratio_to_first'][label]:.2f} of {first}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return result


if __name__ == "__main__":
    main()
