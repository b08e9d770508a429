"""What PPO training costs on this machine: collection, the update per encoder size, a whole iteration.

Measured side by side in one run:

* collection frames/s, with the same env (Laptop by default, point-cloud and camera noise on) and
  the same small-encoder actor-critic choosing every action:
    - ``single_loop``: a plain ``obs -> policy -> env.step`` loop in one process;
    - ``parallel_loop``: that loop in 2 spawned processes at once (a barrier starts them together);
    - ``collector_1``: torchrl's in-process ``Collector`` on one env;
    - ``collector_2``: torchrl's ``MultiSyncCollector`` with 2 worker processes (what ``train`` uses).
  Start-up is excluded everywhere (one warm-up batch first). Ratios ``collector_vs_single_loop`` and
  ``collector_vs_parallel_loop`` compare ``collector_2`` with the plain loops (targets >= 1.6, >= 0.9).
* the PPO update: one Adam step of ``ClipPPOLoss`` on a minibatch of 500 clouds of 608 points, per
  encoder size, with the max-pool backward of ``PointNetEncoder`` (winners only) and, for
  comparison, the plain dense max-pool backward; reported per minibatch, per 10k frames and epoch,
  and for one faithful update (20k frames x 10 epochs);
* a whole training iteration of the ``cpu`` preset (``train``, 2 workers), and the faithful
  preset's iteration computed from the measured parts.

    python benchmarks/bench_training.py --json benchmarks/results/bench_training.json

The machine's 1-minute load average is recorded before and after: on a shared 2-core machine
other processes slow every number down.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import torch
from tensordict import TensorDict

import dexart_lite
from dexart_lite.envs import make as make_gym_env
from dexart_lite.models.actor_critic import encoder_of, make_actor_critic
from dexart_lite.models.pointnet import ENCODER_SIZES
from dexart_lite.rl import ppo
from dexart_lite.rl.env import make_env
from dexart_lite.utils import fast_mode, machine_info

MINIBATCH = 500
POINTS = 512 + 96


# ------------------------------------------------------------------ collection
def plain_loop(task: str, frames: int, seed: int, barrier=None) -> tuple[float, float]:
    """``frames`` policy + env steps in this process; returns (start, end) wall-clock times."""
    torch.set_num_threads(1)
    env = make_gym_env(task, point_noise=True, camera_noise=True)
    actor_critic = make_actor_critic(env.observation_space["state"].shape[0])
    obs, _ = env.reset(seed=seed)

    def step(obs):
        td = TensorDict({"point_cloud": torch.as_tensor(obs["point_cloud"]), "observation": torch.as_tensor(obs["state"])})
        with torch.no_grad():
            action = actor_critic(td)["action"].numpy()
        obs, _, terminated, truncated, _ = env.step(action)
        return env.reset()[0] if terminated or truncated else obs

    for _ in range(20):  # warm-up
        obs = step(obs)
    if barrier is not None:
        barrier.wait()
    start = time.time()
    for _ in range(frames):
        obs = step(obs)
    end = time.time()
    env.close()
    return start, end


def parallel_loop(task: str, frames: int, workers: int = 2) -> float:
    """frames/s of ``workers`` plain loops running at once (``frames`` in total)."""
    ctx = mp.get_context("spawn")
    with ctx.Manager() as manager, ctx.Pool(workers) as pool:
        barrier = manager.Barrier(workers)
        spans = pool.starmap(plain_loop, [(task, frames // workers, i, barrier) for i in range(workers)])
    return frames // workers * workers / (max(e for _, e in spans) - min(s for s, _ in spans))


def collector_fps(task: str, frames: int, workers: int, frames_per_batch: int) -> float:
    """Steady-state frames/s of the collector ``train`` would build (no updates in between)."""
    cfg = dataclasses.replace(ppo.PPOConfig(), task=task, workers=workers, frames_per_batch=frames_per_batch)
    env_fns = [partial(make_env, task, seed=i) for i in range(max(workers, 1))]
    probe = env_fns[0]()
    actor_critic = make_actor_critic(probe.observation_spec["observation"].shape[-1])
    probe.close()
    collector = ppo.make_collector(cfg, env_fns, actor_critic, total_frames=-1)
    batches = iter(collector)
    next(batches)  # warm-up: worker start-up, first resets
    start = time.perf_counter()
    n = 0
    while n < frames:
        n += next(batches).numel()
    fps = n / (time.perf_counter() - start)
    collector.shutdown()
    return fps


# ------------------------------------------------------------------ update
def update_cost(encoder: str, dense: bool, reps: int) -> float:
    """Seconds per ClipPPOLoss + Adam step on a minibatch of 500 clouds (608 points)."""
    from torchrl.objectives import ClipPPOLoss

    torch.manual_seed(0)
    actor_critic = make_actor_critic(32, 22, encoder)
    if dense:  # the plain max-pool: autograd keeps every point's activations
        pointnet = encoder_of(actor_critic)
        pointnet.forward = lambda points: pointnet.mlp(points).max(dim=-2).values
    loss_module = ClipPPOLoss(actor_network=actor_critic.get_policy_operator(),
                              critic_network=actor_critic.get_value_head(), entropy_coeff=0.0, critic_coeff=0.5,
                              loss_critic_type="l2", normalize_advantage=True)
    optimizer = torch.optim.Adam(loss_module.parameters(), lr=1e-4, eps=1e-5)
    batch = TensorDict({"point_cloud": torch.randn(MINIBATCH, POINTS, 3) * 0.3,
                        "observation": torch.randn(MINIBATCH, 32)}, [MINIBATCH])
    with torch.no_grad():
        actor_critic.get_policy_operator()(batch)
    batch["advantage"], batch["value_target"] = torch.randn(MINIBATCH, 1), torch.randn(MINIBATCH, 1)
    times = []
    for i in range(reps + 1):
        start = time.perf_counter()
        out = loss_module(batch.clone())
        loss = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(loss_module.parameters(), 0.5)
        optimizer.step()
        if i:  # the first step is a warm-up
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def training_iteration(task: str, batches: int) -> dict:
    """``train`` with the cpu preset for ``batches`` batches (2 workers, no evaluation)."""
    with tempfile.TemporaryDirectory() as out:
        cfg = ppo.preset("cpu", task=task, frames=batches * ppo.PRESETS["cpu"]["frames_per_batch"], out=out,
                         eval_episodes=0, progress=False)
        history = ppo.train(cfg)["history"][1:]  # the first batch includes the workers' start-up
    n = len(history) * cfg.frames_per_batch
    collect, update = sum(h["collect_s"] for h in history), sum(h["update_s"] for h in history)
    return {"preset": "cpu", "frames_per_batch": cfg.frames_per_batch, "epochs": cfg.epochs, "batches_timed": len(history),
            "collect_fps": n / collect, "update_fps": n / update, "iteration_fps": n / (collect + update),
            "update_s_per_batch": update / len(history), "collect_s_per_batch": collect / len(history)}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="laptop", choices=dexart_lite.TASKS)
    parser.add_argument("--frames", type=int, default=2000, help="timed frames per collection variant")
    parser.add_argument("--reps", type=int, default=5, help="timed minibatches per encoder")
    parser.add_argument("--iteration-batches", type=int, default=3, help="cpu-preset batches (first one not timed)")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    if fast_mode():
        args.frames, args.reps, args.iteration_batches = 200, 1, 2
    torch.set_num_threads(os.cpu_count())
    load_before = os.getloadavg()[0]
    frames_per_batch = min(1000, args.frames)

    fps = {"single_loop": None, "parallel_loop": None, "collector_1": None, "collector_2": None}
    start, end = plain_loop(args.task, args.frames, seed=0)
    fps["single_loop"] = args.frames / (end - start)
    fps["parallel_loop"] = parallel_loop(args.task, args.frames)
    fps["collector_1"] = collector_fps(args.task, args.frames, 1, frames_per_batch)
    fps["collector_2"] = collector_fps(args.task, args.frames, 2, frames_per_batch)

    update = {}
    for encoder in ENCODER_SIZES:
        seconds = update_cost(encoder, dense=False, reps=args.reps)
        dense = update_cost(encoder, dense=True, reps=max(1, args.reps // 2))
        update[encoder] = {"minibatch_s": seconds, "per_10k_frames_per_epoch_s": seconds * 10_000 / MINIBATCH,
                           "faithful_update_s": seconds * 20_000 / MINIBATCH * 10,
                           "dense_maxpool_minibatch_s": dense, "speedup_vs_dense": dense / seconds}

    iteration = training_iteration(args.task, args.iteration_batches)
    faithful_collect = 20_000 / fps["collector_2"]
    faithful_update = update["small"]["faithful_update_s"]
    iteration["faithful_estimate"] = {
        "collect_s": faithful_collect, "update_s": faithful_update,
        "iteration_fps": 20_000 / (faithful_collect + faithful_update),
        "hours_per_1M_frames": 1e6 / (20_000 / (faithful_collect + faithful_update)) / 3600}

    result = {
        "task": args.task,
        "collection_fps": fps,
        "collector_vs_single_loop": fps["collector_2"] / fps["single_loop"],
        "collector_vs_parallel_loop": fps["collector_2"] / fps["parallel_loop"],
        "update": update,
        "iteration": iteration,
        "settings": {"points": POINTS, "minibatch": MINIBATCH, "torch_threads_learner": torch.get_num_threads(),
                     "collection_frames": args.frames, "collector_frames_per_batch": frames_per_batch},
        "load_average_1min": {"before": load_before, "after": os.getloadavg()[0]},
        "command": "python benchmarks/bench_training.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "machine": machine_info(), "torch": torch.__version__,
    }
    print(f"| collection ({args.task}, small-encoder policy) | frames/s |\n|---|---|")
    for k, v in fps.items():
        print(f"| {k} | {v:.0f} |")
    print(f"\ncollector_vs_single_loop = {result['collector_vs_single_loop']:.2f} (target >= 1.6), "
          f"collector_vs_parallel_loop = {result['collector_vs_parallel_loop']:.2f} (target >= 0.9)\n")
    print("| encoder | minibatch of 500 (s) | per 10k frames, 1 epoch (s) | faithful update, 20k x 10 epochs (s) "
          "| dense max-pool minibatch (s) | speed-up |\n|---|---|---|---|---|---|")
    for k, u in update.items():
        print(f"| {k} | {u['minibatch_s']:.3f} | {u['per_10k_frames_per_epoch_s']:.1f} | {u['faithful_update_s']:.0f} | "
              f"{u['dense_maxpool_minibatch_s']:.3f} | {u['speedup_vs_dense']:.1f}x |")
    est = iteration["faithful_estimate"]
    print(f"\ncpu preset iteration ({iteration['frames_per_batch']} frames, {iteration['epochs']} epochs): "
          f"collect {iteration['collect_fps']:.0f} frames/s, update {iteration['update_fps']:.0f} frames/s, "
          f"whole iteration {iteration['iteration_fps']:.0f} frames/s")
    print(f"faithful preset (from the parts): collect {est['collect_s']:.0f} s + update {est['update_s']:.0f} s per "
          f"20k frames = {est['iteration_fps']:.0f} frames/s, {est['hours_per_1M_frames']:.1f} h per 1M frames")
    print(f"load average (1 min): {load_before:.2f} before, {result['load_average_1min']['after']:.2f} after")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
