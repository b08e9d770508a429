"""What PPO training costs on this machine: collection, the update per encoder size, a whole iteration.

Measured side by side in one run:

* collection frames/s, with the same env (Laptop by default, point-cloud and camera noise on) and
  the same small-encoder actor-critic choosing every action:
    - ``single_loop``: a plain ``obs -> policy -> env.step`` loop in one process;
    - ``parallel_loop``: that loop in 2 spawned processes, started together;
    - ``collector_1``: torchrl's in-process ``Collector`` on one env;
    - ``collector_2``: torchrl's ``MultiSyncCollector`` with 2 worker processes (what ``train`` uses),
      yielding batches of ``--collector-batch`` frames (default 4000, the ``cpu`` preset's batch);
    - ``collector_2_batch1000``: the same with batches of 1000 frames: the workers wait for each
      other 4x as often, which shows what synchronising costs.
  Start-up is excluded (every variant is built and warmed up first); then the variants take turns,
  ``--rounds`` times, and the medians are reported, so a busy machine slows them all alike.
  ``collector_vs_single_loop`` and ``collector_vs_parallel_loop`` compare ``collector_2`` with the
  plain loops (targets >= 1.6 and >= 0.9). Every variant acts with ``Acting`` (as ``train``);
* one action on one observation: the actor-critic as torchrl modules and as ``Acting`` (``policy_call_ms``);
* the PPO update: one Adam step of ``ClipPPOLoss`` on a minibatch of 500 clouds of 608 points, per
  encoder size, with the max-pool backward of ``PointNetEncoder`` (winners only) and, for
  comparison, the plain dense max-pool backward (taking turns, medians); reported per minibatch,
  per 10k frames and epoch, and for one faithful update (20k frames x 10 epochs);
* a whole training iteration of the ``cpu`` preset (``train``, 2 workers), and the faithful
  preset's iteration computed from the measured parts.

With ``--ref COMMIT``, the whole ``cpu``-preset iteration is also measured for this checkout and for a
``git worktree`` of that commit, alternately (``--ref-rounds`` times each) in fresh subprocesses of the
same run (``iteration_vs_ref``: this / ref, medians); speed-ups are claimed from this ratio only.

    python benchmarks/perf/bench_training.py --json benchmarks/results/perf/bench_training.json
    python benchmarks/perf/bench_training.py --ref 2f696c9 --json benchmarks/results/perf/bench_training_vs_2f696c9.json

The machine's 1-minute load average is recorded before and after: on a shared 2-core machine
other processes slow every number down.
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing as mp
import os
import statistics
import tempfile
import time
from functools import partial
from pathlib import Path

import torch
from tensordict import TensorDict

from dexart_lite.cli import add_config_arguments
from dexart_lite.envs import make as make_gym_env
from dexart_lite.envs.base import physics_setting
from dexart_lite.models.actor_critic import Acting, encoder_of, make_actor_critic
from dexart_lite.models.pointnet import ENCODER_SIZES
from dexart_lite.rl import ppo
from dexart_lite.rl.env import make_env, torch_threads
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

MINIBATCH = 500
POINTS = 512 + 96
ROOT = Path(__file__).resolve().parents[2]
harness = sibling_script(__file__, "_harness")  # benchmarks/_harness.py: runs of another commit
# ``training_iteration`` as a script, with only the API every commit since 2f696c9 has (``ppo.preset``,
# ``ppo.train``, the history's ``collect_s`` / ``update_s``), for ``--ref``: run in each checkout.
ITERATION = """
import dataclasses, json, os, sys, tempfile
import torch
from dexart_lite.rl import ppo
task, batches, frames_per_batch, workers = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
torch.set_num_threads(os.cpu_count())  # the learner's threads, as in main()
with tempfile.TemporaryDirectory() as out:
    cfg = ppo.preset("cpu", task=task, frames=batches * frames_per_batch, frames_per_batch=frames_per_batch,
                     workers=workers, out=out, eval_episodes=0, progress=False)
    # a batch smaller than the preset's minibatch (the tests' smoke runs) is one minibatch
    cfg = dataclasses.replace(cfg, minibatch=min(cfg.minibatch, frames_per_batch))
    history = ppo.train(cfg)["history"][1:]  # the first batch includes the workers' start-up
n = len(history) * cfg.frames_per_batch
print(json.dumps({"iteration_fps": n / sum(h["collect_s"] + h["update_s"] for h in history)}))
"""


# ------------------------------------------------------------------ collection
class PlainLoop:
    """A plain ``obs -> policy -> env.step`` loop over one env, in this process."""

    def __init__(self, task: str, seed: int):
        self.env = make_gym_env(task, point_noise=True, camera_noise=True)
        self.policy = Acting(make_actor_critic(self.env.observation_space["state"].shape[0]))  # as the collectors
        self.obs, _ = self.env.reset(seed=seed)
        self.run(20)  # warm-up

    def run(self, frames: int) -> None:
        for _ in range(frames):
            td = TensorDict({"point_cloud": torch.as_tensor(self.obs["point_cloud"]),
                             "observation": torch.as_tensor(self.obs["state"])})
            with torch.no_grad():
                action = self.policy(td)["action"].numpy()
            self.obs, _, terminated, truncated, _ = self.env.step(action)
            if terminated or truncated:
                self.obs, _ = self.env.reset()


def _plain_worker(task: str, seed: int, pipe) -> None:
    torch.set_num_threads(1)
    loop = PlainLoop(task, seed)
    pipe.send("ready")
    while (frames := pipe.recv()) > 0:
        loop.run(frames)
        pipe.send("done")


class ParallelPlainLoop:
    """``workers`` plain loops in spawned processes, started together on each ``run``."""

    def __init__(self, task: str, workers: int = 2):
        ctx = mp.get_context("spawn")
        self.pipes, self.procs = [], []
        for i in range(workers):
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_plain_worker, args=(task, i, child), daemon=True)
            proc.start()
            self.pipes.append(parent)
            self.procs.append(proc)
        for pipe in self.pipes:
            assert pipe.recv() == "ready"

    def run(self, frames: int) -> None:
        for pipe in self.pipes:
            pipe.send(frames // len(self.pipes))
        for pipe in self.pipes:
            pipe.recv()

    def close(self) -> None:
        for pipe, proc in zip(self.pipes, self.procs):
            pipe.send(0)
            proc.join()


class CollectorLoop:
    """The collector ``train`` would build (``ppo.make_collector``), iterated without updates."""

    def __init__(self, task: str, workers: int, frames_per_batch: int):
        cfg = dataclasses.replace(ppo.PPOConfig(), task=task, workers=workers, frames_per_batch=frames_per_batch)
        env_fns = [partial(make_env, task, seed=i) for i in range(max(workers, 1))]
        probe = env_fns[0]()
        actor_critic = make_actor_critic(probe.observation_spec["observation"].shape[-1])
        probe.close()
        self.collector = ppo.make_collector(cfg, env_fns, actor_critic, total_frames=-1)
        self.batches = iter(self.collector)
        next(self.batches)  # warm-up: worker start-up, first resets

    def run(self, frames: int) -> None:
        n = 0
        while n < frames:
            n += next(self.batches).numel()

    def close(self) -> None:
        self.collector.shutdown()


def collection_fps(task: str, frames: int, rounds: int, frames_per_batch: int) -> dict[str, float]:
    """Median frames/s of each variant over ``rounds`` rounds; the variants take turns in each round,
    so a busy machine slows them all alike. ``frames`` per variant and round; the collectors yield
    batches of ``frames_per_batch`` (<= ``frames``), split evenly over their workers."""
    variants = {"single_loop": PlainLoop(task, seed=0), "parallel_loop": ParallelPlainLoop(task, 2),
                "collector_1": CollectorLoop(task, 1, frames_per_batch),
                "collector_2": CollectorLoop(task, 2, frames_per_batch),
                "collector_2_batch1000": CollectorLoop(task, 2, min(1000, frames_per_batch))}
    fps: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(rounds):
        for name, variant in variants.items():
            with torch_threads(1):  # in-process loops: as the workers, which use one thread each
                start = time.perf_counter()
                variant.run(frames)
                fps[name].append(frames / (time.perf_counter() - start))
    for variant in variants.values():
        if hasattr(variant, "close"):
            variant.close()
    return {k: statistics.median(v) for k, v in fps.items()}


def policy_call_ms(calls: int, rounds: int) -> dict[str, float]:
    """Median ms per call on one observation (608 points, one thread, no autograd) of the small-encoder
    actor-critic as torchrl modules (``actor_critic(td)``) and as ``Acting`` (what the collectors and
    evaluation run; the same numbers), taking turns ``rounds`` times."""
    actor_critic = make_actor_critic(32, 22, "small", normalize=True)
    policies = {"actor_critic": actor_critic, "acting": Acting(actor_critic)}
    obs = TensorDict({"point_cloud": torch.randn(POINTS, 3) * 0.3, "observation": torch.randn(32)})
    times: dict[str, list[float]] = {k: [] for k in policies}
    with torch.no_grad(), torch_threads(1):
        for _ in range(rounds):
            for name, policy in policies.items():
                policy(obs.clone())  # warm-up
                start = time.perf_counter()
                for _ in range(calls):
                    policy(obs.clone())
                times[name].append((time.perf_counter() - start) / calls * 1e3)
    ms = {k: statistics.median(v) for k, v in times.items()}
    return {**ms, "acting_speedup": ms["actor_critic"] / ms["acting"]}


# ------------------------------------------------------------------ update
class UpdateStep:
    """One ClipPPOLoss + Adam step on a minibatch of 500 clouds (608 points) for ``encoder``.

    ``dense``: the plain max-pool, whose backward keeps every point's activations, for comparison
    with ``PointNetEncoder``'s winner-only backward.
    """

    def __init__(self, encoder: str, dense: bool):
        from torchrl.objectives import ClipPPOLoss

        torch.manual_seed(0)
        actor_critic = make_actor_critic(32, 22, encoder)
        if dense:
            pointnet = encoder_of(actor_critic)
            pointnet.forward = lambda points: pointnet.mlp(points).max(dim=-2).values
        self.loss_module = ClipPPOLoss(actor_network=actor_critic.get_policy_operator(),
                                       critic_network=actor_critic.get_value_head(), entropy_coeff=0.0,
                                       critic_coeff=0.5, loss_critic_type="l2", normalize_advantage=True)
        self.optimizer = torch.optim.Adam(self.loss_module.parameters(), lr=1e-4, eps=1e-5)
        self.batch = TensorDict({"point_cloud": torch.randn(MINIBATCH, POINTS, 3) * 0.3,
                                 "observation": torch.randn(MINIBATCH, 32)}, [MINIBATCH])
        with torch.no_grad():
            actor_critic.get_policy_operator()(self.batch)
        self.batch["advantage"], self.batch["value_target"] = torch.randn(MINIBATCH, 1), torch.randn(MINIBATCH, 1)
        self()  # warm-up

    def __call__(self) -> float:
        start = time.perf_counter()
        out = self.loss_module(self.batch.clone())
        loss = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
        self.optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.loss_module.parameters(), 0.5)
        self.optimizer.step()
        return time.perf_counter() - start


def update_costs(reps: int) -> dict[str, dict[str, float]]:
    """Median seconds per update step, per encoder, winner-only and dense, taking turns ``reps`` times."""
    steps = {(size, dense): UpdateStep(size, dense) for size in ENCODER_SIZES for dense in (False, True)}
    times: dict[tuple, list[float]] = {k: [] for k in steps}
    for _ in range(reps):
        for key, step in steps.items():
            times[key].append(step())
    update = {}
    for size in ENCODER_SIZES:
        seconds, dense = statistics.median(times[size, False]), statistics.median(times[size, True])
        update[size] = {"minibatch_s": seconds, "per_10k_frames_per_epoch_s": seconds * 10_000 / MINIBATCH,
                        "faithful_update_s": seconds * 20_000 / MINIBATCH * 10,
                        "dense_maxpool_minibatch_s": dense, "speedup_vs_dense": dense / seconds}
    return update


class PhysicsPPOConfig(ppo.PPOConfig):
    """A ``PPOConfig`` whose envs use other physics (``physics_setting`` keywords), for ``--physics`` only;
    its fields (what ``train`` records) are the config's."""

    def __init__(self, physics: dict, **fields):
        super().__init__(**fields)
        self.physics = physics

    def env_kwargs(self) -> dict:
        return {**super().env_kwargs(), **self.physics}


def training_iteration(task: str, batches: int, physics: str | None = None) -> dict:
    """``train`` with the cpu preset for ``batches`` batches (2 workers, no evaluation); ``physics``: a
    setting such as ``"20x5"`` for every env of the run (default: the env's, ``"50x10"``)."""
    with tempfile.TemporaryDirectory() as out:
        cfg = ppo.preset("cpu", task=task, frames=batches * ppo.PRESETS["cpu"]["frames_per_batch"], out=out,
                         eval_episodes=0, progress=False)
        if physics:
            cfg = PhysicsPPOConfig(physics_setting(physics), **dataclasses.asdict(cfg))
        history = ppo.train(cfg)["history"][1:]  # the first batch includes the workers' start-up
    n = len(history) * cfg.frames_per_batch
    collect, update = sum(h["collect_s"] for h in history), sum(h["update_s"] for h in history)
    return {"preset": "cpu", "frames_per_batch": cfg.frames_per_batch, "epochs": cfg.epochs, "batches_timed": len(history),
            "collect_fps": n / collect, "update_fps": n / update, "iteration_fps": n / (collect + update),
            "update_s_per_batch": update / len(history), "collect_s_per_batch": collect / len(history)}


def iteration_vs_ref(ref: str, task: str, batches: int, rounds: int,
                     frames_per_batch: int = ppo.PRESETS["cpu"]["frames_per_batch"], workers: int = 2) -> dict:
    """The whole cpu-preset iteration (frames/s) of this checkout and of commit ``ref``, measured alternately
    in fresh subprocesses (``ITERATION``), ``rounds`` times each; medians and their ratio. ``batches``
    includes the first, untimed one."""
    fps: dict[str, list[float]] = {"this": [], "ref": []}
    with harness.git_worktree(ROOT, ref) as ref_root:
        for _ in range(rounds):
            for key, root in (("this", ROOT), ("ref", ref_root)):
                args = (task, str(batches), str(frames_per_batch), str(workers))
                fps[key].append(harness.run_in_checkout(root, ITERATION, *args)["iteration_fps"])
    this, other = statistics.median(fps["this"]), statistics.median(fps["ref"])
    return {"ref": ref, "ref_rounds": rounds, "ref_frames_per_batch": frames_per_batch,
            "ref_workers": workers, "iteration_fps_subprocess": this, "ref_iteration_fps": other,
            "iteration_vs_ref": this / other}


def iteration_vs_physics(setting: str, task: str, batches: int, rounds: int) -> dict:
    """The whole cpu-preset iteration with the env's physics and with ``setting``, alternately in this
    process, ``rounds`` times each: medians of collection, update and iteration frames/s, and the ratio.
    Learning settings are the same; only the envs' physics differs (its success contract:
    ``benchmarks/perf/bench_physics.py``)."""
    runs: dict[str, list[dict]] = {"default": [], setting: []}
    for _ in range(rounds):
        runs["default"].append(training_iteration(task, batches))
        runs[setting].append(training_iteration(task, batches, setting))
    med = {key: {k: statistics.median(r[k] for r in rs) for k in ("collect_fps", "update_fps", "iteration_fps")}
           for key, rs in runs.items()}
    return {"setting": setting, "rounds": rounds, "default": med["default"], "with_setting": med[setting],
            "iteration_vs_default": med[setting]["iteration_fps"] / med["default"]["iteration_fps"]}


def physics_comparison(args) -> dict:
    """``iteration_vs_physics`` for ``--physics``, printed as a table."""
    out = iteration_vs_physics(args.physics, args.task, args.iteration_batches, args.ref_rounds)
    print(f"| cpu-preset iteration, {args.task} (medians of {out['rounds']}) | collect | update | whole iteration |"
          "\n|---|---|---|---|")
    for name, key in (("physics 50x10 (default)", "default"), (f"physics {args.physics}", "with_setting")):
        m = out[key]
        print(f"| {name} | {m['collect_fps']:.0f} | {m['update_fps']:.0f} | {m['iteration_fps']:.0f} |")
    print(f"whole iteration x{out['iteration_vs_default']:.2f} with physics {args.physics}")
    return out


def print_tables(result: dict, ref: str | None) -> None:
    """Collection, policy-call, update and whole-iteration figures as markdown tables and lines."""
    print(f"| collection ({result['task']}, small-encoder policy) | frames/s |\n|---|---|")
    for k, v in result['collection_fps'].items():
        print(f"| {k} | {v:.0f} |")
    print(f"\ncollector_vs_single_loop = {result['collector_vs_single_loop']:.2f} (target >= 1.6), "
          f"collector_vs_parallel_loop = {result['collector_vs_parallel_loop']:.2f} (target >= 0.9)")
    print(f"one action (small encoder, 1 thread): actor_critic(td) {result['policy_call_ms']['actor_critic']:.2f} ms, "
          f"Acting {result['policy_call_ms']['acting']:.2f} ms (x{result['policy_call_ms']['acting_speedup']:.2f})\n")
    print("| encoder | minibatch of 500 (s) | per 10k frames, 1 epoch (s) | faithful update, 20k x 10 epochs (s) "
          "| dense max-pool minibatch (s) | speed-up |\n|---|---|---|---|---|---|")
    for k, u in result['update'].items():
        print(f"| {k} | {u['minibatch_s']:.3f} | {u['per_10k_frames_per_epoch_s']:.1f} | {u['faithful_update_s']:.0f} | "
              f"{u['dense_maxpool_minibatch_s']:.3f} | {u['speedup_vs_dense']:.1f}x |")
    iteration = result["iteration"]
    est = iteration["faithful_estimate"]
    print(f"\ncpu preset iteration ({iteration['frames_per_batch']} frames, {iteration['epochs']} epochs): "
          f"collect {iteration['collect_fps']:.0f} frames/s, update {iteration['update_fps']:.0f} frames/s, "
          f"whole iteration {iteration['iteration_fps']:.0f} frames/s")
    print(f"faithful preset (from the parts): collect {est['collect_s']:.0f} s + update {est['update_s']:.0f} s per "
          f"20k frames = {est['iteration_fps']:.0f} frames/s, {est['hours_per_1M_frames']:.1f} h per 1M frames")
    if ref:
        print(f"cpu preset iteration side by side: this checkout {iteration['iteration_fps_subprocess']:.0f} "
              f"frames/s, {ref} {iteration['ref_iteration_fps']:.0f} frames/s: x{iteration['iteration_vs_ref']:.2f}")


@dataclasses.dataclass
class Flags:
    """This script's own flags; the shared ones come from the harness."""

    collector_batch: int = dataclasses.field(default=ppo.PRESETS["cpu"]["frames_per_batch"], metadata={
        "min": 1, "help": "frames per collector batch (train: 4000 on the cpu preset, 20000 faithful)"})
    reps: int = dataclasses.field(default=5, metadata={"min": 1, "help": "timed minibatches per encoder (median)"})
    iteration_batches: int = dataclasses.field(default=3, metadata={"min": 2, "help": "cpu-preset batches (first one "
                                                                                     "not timed)"})
    ref_rounds: int = dataclasses.field(default=2, metadata={"min": 1, "help": "iterations per checkout with --ref "
                                                                               "(median)"})
    physics: str | None = dataclasses.field(default=None, metadata={
        "help": "also measure the cpu-preset iteration with this physics setting (ITERATIONSxFRAME_SKIP, e.g. 20x5) "
                "against the default, alternately (--ref-rounds each)"})
    only_physics: bool = dataclasses.field(default=False, metadata={"help": "with --physics: measure nothing else"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", frames=4000, helps={"frames": "timed frames per collection variant and round"})
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "rounds", "ref", helps={"rounds": "rounds of the collection variants (median)",
                                                    "ref": "an earlier commit whose whole cpu-preset iteration is "
                                                           "measured side by side"})
    harness.options(parser, "json")
    args = parser.parse_args(argv)
    if args.physics:
        physics_setting(args.physics)  # a bad setting fails now, not after the other measurements
    elif args.only_physics:
        parser.error("--only-physics needs --physics")
    if fast_mode():
        args.frames, args.rounds, args.reps, args.iteration_batches, args.ref_rounds = 200, 1, 1, 2, 1
    torch.set_num_threads(os.cpu_count())
    load_before = os.getloadavg()[0]
    if args.only_physics:
        result = {"task": args.task, "iteration_vs_physics": physics_comparison(args),
                  "load_average_1min": {"before": load_before, "after": os.getloadavg()[0]},
                  **provenance(__file__, argv), "torch": torch.__version__}
        if args.json:
            write_json(args.json, result)
        return result

    collector_batch = min(args.collector_batch, args.frames)
    fps = collection_fps(args.task, args.frames, args.rounds, collector_batch)
    policy_ms = policy_call_ms(50 if fast_mode() else 500, args.rounds)

    update = update_costs(args.reps)

    iteration = training_iteration(args.task, args.iteration_batches)
    faithful_collect = 20_000 / fps["collector_2"]
    faithful_update = update["small"]["faithful_update_s"]
    iteration["faithful_estimate"] = {
        "collect_s": faithful_collect, "update_s": faithful_update,
        "iteration_fps": 20_000 / (faithful_collect + faithful_update),
        "hours_per_1M_frames": 1e6 / (20_000 / (faithful_collect + faithful_update)) / 3600}
    if args.ref:
        iteration.update(iteration_vs_ref(args.ref, args.task, args.iteration_batches, args.ref_rounds))
    physics = physics_comparison(args) if args.physics else None

    result = {
        "task": args.task,
        "collection_fps": fps,
        "collector_vs_single_loop": fps["collector_2"] / fps["single_loop"],
        "collector_vs_parallel_loop": fps["collector_2"] / fps["parallel_loop"],
        "policy_call_ms": policy_ms,
        "update": update,
        "iteration": iteration,
        **({"iteration_vs_physics": physics} if physics else {}),
        "settings": {"points": POINTS, "minibatch": MINIBATCH, "torch_threads_learner": torch.get_num_threads(),
                     "collection_frames_per_round": args.frames, "rounds": args.rounds,
                     "collector_frames_per_batch": collector_batch},
        "load_average_1min": {"before": load_before, "after": os.getloadavg()[0]},
        **provenance(__file__, argv), "torch": torch.__version__,
    }
    print_tables(result, args.ref)
    print(f"load average (1 min): {load_before:.2f} before, {result['load_average_1min']['after']:.2f} after")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
