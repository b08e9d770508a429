"""Does learning on a GPU pay? A short PPO run and a short distillation per device, side by side on one machine.

    python benchmarks/perf/device_check.py                      # cpu and cuda (needs an NVIDIA GPU)
    python benchmarks/perf/device_check.py --devices cpu        # the CPU half alone (what CI's fast mode runs)

For each ``--devices`` entry, in the same process, one after the other: ``dexart-lite train --preset cpu
--frames F --workers W --eval-episodes 0 --device D`` on ``--task`` and ``dexart-lite distill --rounds 1
--device D`` (``--demo-episodes`` expert episodes per seen object, ``--epochs`` epochs of BC, then one DAgger
round of half as many episodes; the student acts on the CPU). Collection stays on
the CPU in both, so the device changes the update only: the figures are the PPO update's frames/s (the
median over batches, the first batch left out as warm-up), the collection's frames/s beside it, and the
distillation's BC seconds. Written to ``benchmarks/results/perf/device_check.json``: per device ``ppo`` (frames,
update_fps, collect_fps, wall_s) and ``distill`` (samples, bc_s, round_train_s), the ratios against the
first device, the command and the machine (CPU, cores, GPU name, CUDA and torch versions). A device that
is not there is a one-line error (no silent fallback), so the figure is never a CPU one under a GPU's name.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import torch

from dexart_lite.cli import add_config_arguments
from dexart_lite.imitation.distill import DistillConfig, distill
from dexart_lite.objects import list_objects
from dexart_lite.rl import ppo
from dexart_lite.utils import (benchmark_results, fast_mode, machine_info, provenance, resolve_device, sibling_script,
                               write_json)

RESULTS = benchmark_results(__file__) / "device_check.json"
harness = sibling_script(__file__, "_harness")


def ppo_figures(task: str, device: str, frames: int, workers: int, out: Path) -> dict:
    size = {"frames_per_batch": 200, "minibatch": 100, "epochs": 1, "num_points": 64} if fast_mode() else {}
    cfg = ppo.preset("cpu", task=task, frames=frames, workers=workers, eval_episodes=0, progress=False,
                     device=device, out=str(out), **size)
    result = ppo.train(cfg)
    rows = result["history"][1:] or result["history"]  # the first batch warms up (allocations, kernels)
    return {"frames": result["frames"], "update_fps": statistics.median(r["update_fps"] for r in rows),
            "collect_fps": statistics.median(r["collect_fps"] for r in rows),
            "wall_s": round(sum(r["collect_s"] + r["update_s"] for r in result["history"]), 1),
            "frames_per_batch": cfg.frames_per_batch, "epochs": cfg.epochs, "minibatch": cfg.minibatch}


def distill_figures(task: str, device: str, epochs: int, demo_episodes: int, out: Path) -> dict:
    size = dict(num_points=64, max_episode_steps=10, demo_episodes_per_object=1, episodes_per_round=1,
                objects=list_objects(task, "seen")[0].name) if fast_mode() else \
        dict(demo_episodes_per_object=demo_episodes, episodes_per_round=max(1, demo_episodes // 2))
    cfg = DistillConfig(task=task, rounds=1, epochs=epochs, epochs_per_round=epochs, eval_episodes=0,
                        progress=False, device=device, out=str(out), **size)
    result = distill(cfg)
    bc, rounds = result["history"][0], result["history"][1:]
    return {"samples": bc["buffer"], "epochs": epochs, "bc_s": round(bc["train_s"], 2),
            "round_train_s": [round(r["train_s"], 2) for r in rounds]}


@dataclass
class Flags:
    """This script's own flag; the shared ones come from the harness."""

    devices: list[str] = field(default_factory=lambda: ["cpu", "cuda"],
                               metadata={"choices": ["cpu", "cuda"], "help": "the devices compared"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "task", frames=24_000, helps={"frames": "PPO frames per device (6 batches of 4,000)"})
    add_config_arguments(parser, ppo.PPOConfig, names=["workers", "demo_episodes"], overrides=False,
                         defaults={"workers": 2, "demo_episodes": 4},
                         helps={"workers": "PPO collector processes", "demo_episodes": "expert episodes per seen "
                                "object for BC (the DAgger round runs half as many)"})
    harness.options(parser, epochs=5, helps={"epochs": "distillation BC epochs per device"})
    harness.options(parser, json=RESULTS)
    args = parser.parse_args(argv)
    if fast_mode() and args.json == RESULTS:
        raise ValueError("fast mode writes smoke results: pass --json elsewhere")
    for device in args.devices:
        resolve_device(device)  # cuda on a machine without it: one line, before any run
    per_device = {}
    with tempfile.TemporaryDirectory() as scratch:
        for device in args.devices:
            per_device[device] = {"ppo": ppo_figures(args.task, device, args.frames, args.workers,
                                                     Path(scratch) / f"ppo_{device}"),
                                  "distill": distill_figures(args.task, device, args.epochs, args.demo_episodes,
                                                             Path(scratch) / f"distill_{device}")}
            print(f"{device}: PPO update {per_device[device]['ppo']['update_fps']:.0f} frames/s, "
                  f"distillation BC {per_device[device]['distill']['bc_s']:.1f} s")
    first = per_device[args.devices[0]]
    ratios = {d: {"ppo_update_fps": r["ppo"]["update_fps"] / first["ppo"]["update_fps"],
                  "distill_bc_speedup": first["distill"]["bc_s"] / max(r["distill"]["bc_s"], 1e-9)}
              for d, r in per_device.items()}
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    result = {"task": args.task, "per_device": per_device, "ratios_vs_first": ratios,
              **provenance(__file__, argv),
              "machine": {**machine_info(), "gpu": gpu, "cuda": torch.version.cuda, "torch": torch.__version__,
                          "torch_threads": torch.get_num_threads()}}
    write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
