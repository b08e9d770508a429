"""How collection scales with workers, and where the machine (not the code) flattens the curve.

    python benchmarks/perf/bench_scaling.py                               # 1..cores workers, process backend (+ ray if installed)
    python benchmarks/perf/bench_scaling.py --workers 1 2 4 8 16 --backends process ray

Two measurements, side by side in one run:

* ``collection``: frames/s of the collector ``dexart-lite train`` builds (``ppo.make_collector``: the
  small-PointNet actor-critic choosing every action, point-cloud observation) for each ``--backends`` entry
  and each worker count, ``--frames`` frames per setting after a warm-up batch (worker start-up excluded);
  batches of ``--per-worker`` frames per worker. ``ray`` is measured only where Ray is installed
  (``pip install '.[distributed]'``); otherwise the JSON says it was not.
* ``plain_env``: ``env.step`` calls per second with random actions in N processes started together (no
  policy, no torchrl), the total and per process: where per-process speed falls as N grows, the cores
  (or memory bandwidth) are the limit, not the collector.

Written to ``benchmarks/results/perf/bench_scaling.json`` (``collection[backend][workers]`` frames/s,
``plain_env[N]`` total and per_process steps/s, ``cores``, ``ray`` (installed or why not), command,
machine, load average before and after) and a PNG beside it. Run alone: other jobs on the same cores
change every number.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import time
from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dexart_lite.cli import add_config_arguments  # noqa: E402
from dexart_lite.models.actor_critic import make_actor_critic  # noqa: E402
from dexart_lite.rl import ppo  # noqa: E402
from dexart_lite.rl.env import make_env  # noqa: E402
from dexart_lite.rollout import parallel_step_rates  # noqa: E402
from dexart_lite.utils import (benchmark_results, fast_mode, provenance, save_figure, sibling_script,  # noqa: E402
                               write_json)

RESULTS = benchmark_results(__file__) / "bench_scaling.json"
harness = sibling_script(__file__, "_harness")


def collection_fps(task: str, backend: str, workers: int, frames: int, per_worker: int, env_kwargs: dict) -> float:
    """Frames/s of ``ppo.make_collector`` with ``workers`` workers, after one warm-up batch."""
    cfg = dataclasses.replace(ppo.PPOConfig(), task=task, backend=backend, workers=workers,
                              frames_per_batch=per_worker * workers)
    env_fns = [partial(make_env, task, seed=i, **env_kwargs) for i in range(workers)]
    probe = env_fns[0]()
    actor_critic = make_actor_critic(probe.observation_spec["observation"].shape[-1])
    probe.close()
    # a finite total: torchrl's RayCollector yields nothing for -1 ("endless" to the other collectors)
    collector = ppo.make_collector(cfg, env_fns, actor_critic, total_frames=frames + 2 * cfg.frames_per_batch)
    try:
        batches = iter(collector)
        next(batches)  # warm-up: worker start-up and first resets
        start, n = time.perf_counter(), 0
        while n < frames:
            n += next(batches).numel()
        return n / (time.perf_counter() - start)
    finally:
        collector.shutdown()


def plain_env_rate(task: str, processes: int, steps: int, env_kwargs: dict) -> dict:
    """``env.step`` calls/s (random actions, ``rollout.random_actions``) of ``processes`` spawned processes
    stepping at once: total and per process."""
    rates = parallel_step_rates(task, steps, processes, **env_kwargs)
    return {"total": float(sum(rates)), "per_process": float(np.mean(rates))}


def plot(result: dict, path: Path) -> Path:
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for backend, by_workers in result["collection"].items():
        left.plot([int(k) for k in by_workers], list(by_workers.values()), "o-", label=backend)
    left.set(xlabel="collector workers", ylabel="frames/s", title="collection (PointNet policy acting)")
    left.legend()
    counts = [int(k) for k in result["plain_env"]]
    right.plot(counts, [v["total"] for v in result["plain_env"].values()], "o-", label="total")
    right.plot(counts, [v["per_process"] for v in result["plain_env"].values()], "s--", label="per process")
    right.set(xlabel="processes", ylabel="env steps/s", title=f"plain env.step, {result['cores']} cores")
    right.legend()
    return save_figure(fig, path)


@dataclasses.dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    workers: list[int] = dataclasses.field(default_factory=lambda: [1], metadata={
        "help": "collector workers, one setting each (the default: 1 up to this machine's cores)"})
    backends: list[str] = dataclasses.field(default_factory=lambda: ["process", "ray"],
                                            metadata={"choices": ["process", "ray"], "help": "the collection backends"})
    per_worker: int = dataclasses.field(default=500, metadata={"min": 1, "help": "frames per worker per batch"})


def main(argv=None) -> dict:
    cores = os.cpu_count() or 1
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task")
    add_config_arguments(parser, Flags, overrides=False, defaults={"workers": list(range(1, cores + 1))})
    harness.options(parser, frames=4000, helps={"frames": "timed frames per setting"})
    harness.options(parser, steps=1000, json=RESULTS, helps={"steps": "env steps per process (plain_env)"})
    args = parser.parse_args(argv)
    if fast_mode() and args.json == RESULTS:
        raise ValueError("fast mode writes smoke results: pass --json elsewhere")
    env_kwargs = {"num_points": 64, "max_episode_steps": 20} if fast_mode() else {}
    has_ray = importlib.util.find_spec("ray") is not None
    backends = [b for b in args.backends if b != "ray" or has_ray]
    load_before = os.getloadavg()[0]
    collection = {b: {str(n): collection_fps(args.task, b, n, args.frames, args.per_worker, env_kwargs)
                      for n in args.workers} for b in backends}
    plain = {str(n): plain_env_rate(args.task, n, args.steps, env_kwargs) for n in args.workers}
    result = {"task": args.task, "cores": cores, "collection": collection, "plain_env": plain,
              "frames_per_setting": args.frames, "per_worker_batch": args.per_worker, "steps_per_process": args.steps,
              "ray": "measured" if "ray" in backends else
                     ("not installed (pip install '.[distributed]')" if not has_ray else "not asked for"),
              **provenance(__file__, argv),
              "load_average_1min": {"before": load_before, "after": os.getloadavg()[0]}}
    result["png"] = str(plot(result, args.json.with_suffix(".png")))
    write_json(args.json, result)
    for backend, rows in collection.items():
        print(backend, ", ".join(f"{n} workers {fps:.0f} frames/s" for n, fps in rows.items()))
    print("plain env", ", ".join(f"{n} processes {v['total']:.0f} steps/s" for n, v in plain.items()))
    return result


if __name__ == "__main__":
    main()
