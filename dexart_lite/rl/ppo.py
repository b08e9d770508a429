"""Point-cloud PPO with torchrl: ``train(cfg)`` for a ``PPOConfig`` (``rl/ppo_config.py``).

    dexart-lite train --task laptop --encoder small --frames 1000000 --workers 2 --out runs/laptop
    dexart-lite train --task laptop --preset cpu --frames 60000 --out runs/laptop_cpu

``train`` reads top to bottom: env factory and actor-critic -> collector -> GAE -> ClipPPOLoss ->
the minibatch loop -> logging -> checkpoint; then the evaluation on seen and unseen objects and
``report.md``. The defaults of ``PPOConfig`` are DexArt's PPO settings (``preset="faithful"``);
``PRESETS["cpu"]`` is the measured cheaper variant used by the demo (see ``PRESETS``). The optional
starts and terms (``--init-from``, demonstrations, BC, DAgger) live in ``rl/warmstart.py``, the KL anchor
in ``rl/anchor.py``, self-imitation in ``rl/sil.py``.

Collection (``--backend``): ``process`` runs ``MultiSyncCollector`` with ``--workers`` spawned
processes (an in-process ``Collector`` for 0 or 1 worker); ``distributed`` hands it to torchrl's
``DistributedCollector`` (torch.distributed, gloo; here launched with the ``mp`` launcher on one
machine: see that class for SLURM via submitit); ``ray`` to torchrl's ``RayCollector``, an
optional extra::

    pip install ".[distributed]"            # installs ray
    ray start --head                         # on the head node; `ray start --address=HEAD:6379` on the others
    dexart-lite train --backend ray --ray-address auto --workers 8 ...

Everything is synchronous, as in DexArt's SB3: collect a batch with the current weights, update,
push the weights to the collectors, collect again.
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path

import torch
from tqdm import tqdm

from dexart_lite.models.actor_critic import (Acting, DetachedInput, action_log_std, architecture, encoder_of,
                                             make_actor_critic, set_action_log_std)
from dexart_lite.models.pointnet import load_encoder
from dexart_lite.rl.anchor import add_anchor, anchor_kl, anchor_weight, frozen_policy
from dexart_lite.rl.checkpoint import load_checkpoint, network_encoder, save_checkpoint
from dexart_lite.rl.common import (CHECKPOINT, batch_stats, evaluate_and_report, make_curriculum, progress_bar,
                                   value_error_at_start)
from dexart_lite.rl.curriculum import Curriculum, send_level
from dexart_lite.rl.env import env_dims, make_env
from dexart_lite.rl.ppo_config import PRESETS, PPOConfig, preset, validate
from dexart_lite.rl.sil import SelfImitationBuffer, sil_loss
from dexart_lite.rl.warmstart import (bc_loss, bc_weight, demonstrations, init_normalization, initial_weights,
                                      warmstart_evaluation)
from dexart_lite.utils import optimizer_to, release_freed_memory, resident_mb, resolve_device, to_cpu

LOSS_KEYS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "kl_approx", "clip_fraction",
             "explained_variance")
# what the loss reads from a batch; the rest (next observations, info) is dropped before the epochs
BATCH_KEYS = ("point_cloud", "observation", "action", "action_log_prob", "advantage", "value_target")
SIL_KEYS = ("loss_sil", "loss_sil_value", "sil_positive")  # logged with --sil-coef (rl/sil.py)


# ---------------------------------------------------------------- the learner
@dataclass
class Learner:
    """The actor-critic and everything that updates it (built once per run by ``build_learner``)."""

    actor_critic: torch.nn.Module
    loss_module: torch.nn.Module  # ClipPPOLoss
    optimizer: torch.optim.Optimizer
    trainable: list
    gae: torch.nn.Module
    value_operator: torch.nn.Module  # V(s) alone, for the bootstrap values GAE needs
    dims: dict  # num_points, state_dim, action_dim of the env; head and normalize of the network
    bc_data: object = None  # the --bc-demos samples (a memory-mapped TensorDict) or None
    anchor: torch.nn.Module | None = None  # a frozen copy of the --init-from policy (--anchor-coef) or None
    sil: SelfImitationBuffer | None = None  # the best episodes so far (--sil-coef) or None
    critic: torch.nn.Module | None = None  # the value head the loss trains (fed detached features with --critic-detach)
    demos: dict | None = None  # --demo-episodes: their frames (not online frames), the guide's success, BC losses
    device: torch.device = torch.device("cpu")  # of the networks, the loss and the optimizer (``Learner.to``)

    def to(self, device: torch.device) -> torch.nn.Module:
        """Move the networks (the loss module's too) to ``device``; the optimizer keeps the same parameters.
        Returns the module the collectors and evaluation act with: the actor-critic itself on the CPU, else a
        CPU copy of it that ``sync_acting`` refreshes after every update."""
        self.device = torch.device(device)
        if self.device.type == "cpu":
            return self.actor_critic
        acting = copy.deepcopy(self.actor_critic)
        for module in (self.actor_critic, self.loss_module, self.value_operator, self.critic, self.anchor):
            if module is not None:
                module.to(self.device)
        optimizer_to(self.optimizer, self.device)  # a resumed run's Adam moments were loaded on the CPU
        return acting

    def sync_acting(self, acting: torch.nn.Module) -> None:
        """The CPU copy ``acting`` (``Learner.to``) takes the learner's current weights."""
        if acting is not self.actor_critic:
            acting.load_state_dict(self.actor_critic.state_dict())


def open_run(cfg: PPOConfig) -> Path:
    """Check ``cfg`` and the output folder (a finished run is never overwritten without --resume)."""
    validate(cfg)
    out = Path(cfg.out)
    if (out / CHECKPOINT).exists() and not cfg.resume:
        raise ValueError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
    if cfg.resume and not (out / CHECKPOINT).exists():
        raise FileNotFoundError(f"--resume: no checkpoint in {out}")
    out.mkdir(parents=True, exist_ok=True)
    return out


def initial_actor_critic(cfg: PPOConfig, env_fn) -> tuple[torch.nn.Module, dict]:
    """(actor-critic, dims): from scratch or from ``--init-from``, its input normalisation fixed with
    ``--obs-norm-steps``; dims are the env's sizes and the network's architecture, as checkpoints keep them."""
    probe = env_fn()
    num_points, state_dim, action_dim = env_dims(probe)
    probe.close()
    arch, weights = initial_weights(cfg, state_dim, action_dim)
    if (cfg.obs_norm_steps or cfg.demo_episodes) and weights is None:
        arch["normalize"] = True
    actor_critic = make_actor_critic(state_dim, action_dim, network_encoder(asdict(cfg)), cfg.init_log_std, **arch)
    if cfg.obs_norm_steps and not cfg.resume:  # a resumed run loads the statistics with the weights
        init_normalization(actor_critic, env_fn, cfg.obs_norm_steps, cfg.seed)
    if weights is not None:  # strict: every weight of the student, the input normalisation included
        actor_critic.load_state_dict(weights, strict=True)
        set_action_log_std(actor_critic, cfg.init_log_std)  # the student's log-std was never trained (MSE)
    dims = {"num_points": num_points, "state_dim": state_dim, "action_dim": action_dim,
            **{k: list(v) if isinstance(v, tuple) else v for k, v in architecture(arch).items()}}
    return actor_critic, dims


def build_learner(cfg: PPOConfig, env_fn) -> Learner:
    """Actor-critic (from scratch, from ``--init-from``, or with a pretrained and optionally frozen PointNet),
    the warm start on demonstrations, ClipPPOLoss, Adam and GAE."""
    from torchrl.modules import ValueOperator
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    actor_critic, dims = initial_actor_critic(cfg, env_fn)
    bc_data, demo_info = demonstrations(cfg, actor_critic)  # with --demo-episodes: the cloned actor
    if cfg.pretrained:
        load_encoder(cfg.pretrained, encoder_of(actor_critic), strict=True)
    if cfg.freeze_encoder:
        encoder_of(actor_critic).requires_grad_(False)
    # the critic is the value HEAD, so the trunk runs once per minibatch (it reads the actor's "hidden")
    critic = actor_critic.get_value_head()
    if cfg.critic_detach:  # same value MLP and weights, fed a detached copy of the trunk's features
        critic = ValueOperator(DetachedInput(critic.module), in_keys=list(critic.in_keys))
    loss_module = ClipPPOLoss(actor_network=actor_critic.get_policy_operator(),
                              critic_network=critic, clip_epsilon=cfg.clip_epsilon,
                              entropy_coeff=cfg.entropy_coef, critic_coeff=cfg.vf_coef, loss_critic_type="l2",
                              normalize_advantage=cfg.normalize_advantage)
    trainable = [p for p in loss_module.parameters() if p.requires_grad]
    value_head = set(actor_critic.get_value_head().parameters())
    groups = [{"params": [p for p in trainable if p not in value_head]},
              {"params": [p for p in trainable if p in value_head], "lr": cfg.critic_lr or cfg.lr}]
    optimizer = torch.optim.Adam(groups, lr=cfg.lr, eps=cfg.adam_eps)
    gae = GAE(gamma=cfg.gamma, lmbda=cfg.lmbda, value_network=None, average_gae=False)  # reads the values
    # the student as loaded, before any update (a resumed run reloads it from --init-from)
    anchor = frozen_policy(actor_critic) if cfg.anchor_coef > 0 else None
    sil = SelfImitationBuffer(cfg.sil_capacity, cfg.gamma) if cfg.sil_coef > 0 else None
    return Learner(actor_critic, loss_module, optimizer, trainable, gae, actor_critic.get_value_operator(), dims,
                   bc_data, anchor, sil, critic, demo_info)


def restore(learner: Learner, cfg: PPOConfig, path: Path, curriculum: Curriculum | None = None) -> tuple[int, int, list]:
    """Weights, optimizer and curriculum from a checkpoint of the same task and encoder; (frames, batches, history)."""
    state = load_checkpoint(path)
    if curriculum is not None:
        if state.get("curriculum") is None:
            raise ValueError(f"--resume: {path} was trained without a curriculum; resume it with --curriculum none")
        curriculum.load_state_dict(state["curriculum"])
    if state["config"]["encoder"] != cfg.encoder or state["config"]["task"] != cfg.task:
        raise ValueError(f"--resume: {path} is a {state['config']['encoder']} {state['config']['task']} "
                         f"run, not {cfg.encoder} {cfg.task}")
    try:
        learner.actor_critic.load_state_dict(state["model"], strict=True)
    except RuntimeError:
        raise ValueError(f"--resume: {path} holds a network of another shape (its architecture: "
                         f"{architecture(state['dims'])}); resume with the same --head / --state-hidden") from None
    learner.optimizer.load_state_dict(state["optimizer"])
    if learner.demos is not None and state.get("demos"):  # what the first invocation measured of the warm start
        # "frames": the demonstration steps the run took (its DAgger rounds included); a resumed run's BC term
        # replays only the re-collected demonstrations ("bc_samples")
        learner.demos["bc_samples"] = learner.demos["frames"]
        learner.demos.update(state["demos"])
    return state["frames"], state["batches"], state["history"]


def save(learner: Learner, cfg: PPOConfig, path: Path, frames: int, batches: int, history: list,
         curriculum: Curriculum | None = None) -> Path:
    """The run's state: weights, optimizer, counters, history and the curriculum's schedule (frontiers,
    streaks). Not kept: the workers' env and RNG states (a resumed run collects on new seeds) and the
    self-imitation buffer."""
    return save_checkpoint(path, {
        "config": asdict(cfg), "model": to_cpu(learner.actor_critic.state_dict()),
        "optimizer": to_cpu(learner.optimizer.state_dict()),
        "frames": frames, "batches": batches, "history": history, "dims": learner.dims,
        "curriculum": curriculum.state_dict() if curriculum is not None else None, "demos": learner.demos})


# ---------------------------------------------------------------- collection and advantages
def make_collector(cfg: PPOConfig, env_fns: list, actor_critic, total_frames: int):
    """The collector of ``cfg.backend``; worker ``i`` builds its own env with ``env_fns[i]``. It acts with
    ``Acting(actor_critic)``: the whole actor-critic's outputs (action and value in one trunk pass) on
    the same weights, without tensordict's per-module overhead."""
    from torchrl.collectors import Collector, MultiSyncCollector

    policy = Acting(actor_critic)
    common = dict(frames_per_batch=cfg.frames_per_batch, total_frames=total_frames)
    if cfg.backend == "process" and cfg.workers <= 1:
        return Collector(env_fns[0], policy, **common)
    if cfg.backend == "process":  # num_threads: keep this process's torch threads for the update
        return MultiSyncCollector(env_fns, policy, num_threads=torch.get_num_threads(), **common)
    if cfg.backend == "distributed":
        from torchrl.collectors.distributed import DistributedCollector

        return DistributedCollector(env_fns, policy, launcher="mp", sync=True, tcp_port=str(cfg.tcp_port), **common)
    from torchrl.collectors.distributed import RayCollector  # cfg.backend == "ray", checked by validate

    return RayCollector(env_fns, policy, sync=True, remote_configs={"num_cpus": 1},
                        ray_init_config={"address": cfg.ray_address} if cfg.ray_address else None, **common)


def add_next_values(data, value_operator) -> None:
    """Write ``("next", "state_value")`` for GAE, from the values the collector recorded.

    The collector runs the whole actor-critic, so ``data["state_value"]`` already holds V(s_t)
    computed with the current weights (as SB3's rollout buffer). V(s_{t+1}) is the next entry in
    time, except where the next observation is not the next root one: after a time-limit
    truncation (bootstrapped, as SB3) and at the end of the batch; only those are evaluated here.
    After a termination the next value is masked out by GAE. data: (workers, T) or (T,).
    """
    value = data["state_value"]  # (..., T, 1)
    next_value = torch.roll(value, shifts=-1, dims=-2).clone()
    fresh = data["next", "truncated"].squeeze(-1).clone()  # (..., T)
    fresh[..., -1] = True
    next_value[fresh] = value_operator(data["next"][fresh])["state_value"]
    data["next", "state_value"] = next_value


def advantages(data, learner: Learner, reward_scale: float = 1.0):
    """GAE over time (the last batch dimension), once per batch as SB3, on the rewards times
    ``reward_scale``; the flat batch the loss reads."""
    with torch.no_grad():
        if reward_scale != 1.0:
            data["next", "reward"] = data["next", "reward"] * reward_scale
        add_next_values(data, learner.value_operator)
        learner.gae(data)
    return data.reshape(-1).select(*BATCH_KEYS, strict=False)


# ---------------------------------------------------------------- the update
def ppo_update(flat, learner: Learner, cfg: PPOConfig, batch: int = 0) -> dict:
    """``cfg.epochs`` passes of clipped-PPO minibatch steps over one batch; the mean of each loss term.

    ``batch`` (0-based) < ``cfg.critic_warmup``: only the value loss, and only the value head steps (the
    trunk is shared, so the actor stays exactly as it was). Otherwise ``minibatch_loss`` adds the terms
    that are on: BC, the KL anchor and self-imitation."""
    warmup, bc, anchor = batch < cfg.critic_warmup, bc_weight(cfg, batch), anchor_weight(cfg, batch)
    if learner.anchor is not None and not warmup:
        add_anchor(flat, learner.anchor)
    value_head = set(learner.actor_critic.get_value_head().parameters())
    generator = torch.Generator().manual_seed(cfg.seed * 100_003 + batch)
    sil = learner.sil if learner.sil is not None and len(learner.sil) and not warmup else None
    sums, steps = dict.fromkeys(LOSS_KEYS + ("loss_bc", "kl_init") + SIL_KEYS, 0.0), 0
    planned = cfg.epochs * math.ceil(flat.numel() / cfg.minibatch)
    stopped = False
    for _ in range(cfg.epochs):
        for idx in torch.randperm(flat.numel()).split(cfg.minibatch):
            loss_td = learner.loss_module(flat[idx])
            # SB3's early stop: this minibatch already sees a policy too far from the collecting one. Not
            # before the first step: the policy is then the collecting one, and its KL is float32 noise
            # (measured 7.6e-8 between the collection's and the loss's log-probabilities).
            if (not warmup and steps > 0 and cfg.target_kl is not None
                    and float(loss_td["kl_approx"]) > 1.5 * cfg.target_kl):
                stopped = True
                break
            if warmup:
                loss = loss_td["loss_critic"]
            else:
                loss = minibatch_loss(loss_td, flat, idx, learner, cfg, bc, anchor, sil, generator)
            gradient_step(learner, loss, cfg.max_grad_norm, frozen_actor=warmup, value_head=value_head)
            for key in sums:
                sums[key] += float(loss_td[key].detach()) if key in loss_td.keys() else 0.0
            steps += 1
        if stopped:
            break
    return {**{k: v / max(steps, 1) for k, v in sums.items()}, "critic_warmup": float(warmup), "bc_weight": bc,
            "anchor_weight": anchor, "update_steps_frac": steps / planned}


def minibatch_loss(loss_td, flat, idx, learner: Learner, cfg: PPOConfig, bc: float, anchor: float, sil,
                   generator: torch.Generator) -> torch.Tensor:
    """Clipped PPO's loss on the minibatch ``flat[idx]`` plus the terms that are on: the BC term (weight
    ``bc``), the KL to the initial policy (weight ``anchor``) and self-imitation on as many steps of the best
    episodes (``sil``, the buffer, or None); each term is written into ``loss_td`` for the log."""
    policy = learner.actor_critic.get_policy_operator()
    loss = loss_td["loss_objective"] + loss_td["loss_critic"] + loss_td["loss_entropy"]
    if bc > 0:
        loss_td["loss_bc"] = bc_loss(policy, learner.bc_data, len(idx), generator, learner.device)
        loss = loss + bc * loss_td["loss_bc"]
    if learner.anchor is not None:
        loss_td["kl_init"] = anchor_kl(policy, flat[idx])
        loss = loss + anchor * loss_td["kl_init"]
    if sil is not None:
        term, parts = sil_loss(policy, learner.critic, sil.sample(len(idx), generator).to(learner.device),
                               cfg.sil_value_coef)
        loss = loss + cfg.sil_coef * term
        loss_td.update({k: torch.tensor(v) for k, v in parts.items()})  # floats -> the loss's 0-d tensors
    return loss


def gradient_step(learner: Learner, loss: torch.Tensor, max_grad_norm: float, frozen_actor: bool,
                  value_head: set) -> None:
    """One Adam step on ``loss``, gradients clipped to ``max_grad_norm``; with ``frozen_actor`` only the
    parameters in ``value_head`` move."""
    learner.optimizer.zero_grad()
    loss.backward()
    if frozen_actor:  # Adam skips parameters without a gradient: the actor does not move at all
        for p in learner.trainable:
            if p not in value_head:
                p.grad = None
    torch.nn.utils.clip_grad_norm_(learner.trainable, max_grad_norm)
    learner.optimizer.step()


def learn(data, learner: Learner, acting, cfg: PPOConfig, batch: int, device: torch.device) -> tuple:
    """One collected batch learnt from: advantages, the PPO update (on ``device``), the acting copy synced.
    Returns the batch on the CPU (its rewards scaled by ``cfg.reward_scale``) and the update's mean losses."""
    data = data.contiguous()  # the distributed collector yields a lazy stack of the workers' batches
    on_device = device.type != "cpu"
    data = data.to(device) if on_device else data
    flat = advantages(data, learner, cfg.reward_scale)  # the rewards in data are scaled from here on
    if learner.sil is not None:  # the batch's finished episodes join the best ones (before the update)
        learner.sil.add(data)
    losses = ppo_update(flat, learner, cfg, batch)
    learner.sync_acting(acting)
    return (data.cpu() if on_device else data), losses  # the log and the curriculum read it on the CPU


# ---------------------------------------------------------------- training
def start_collector(cfg: PPOConfig, env_fn, acting, curriculum: Curriculum | None, frames_done: int, batches: int):
    """The collector of the frames still to collect (None when there are none). It runs the whole actor-critic
    (action + value in one trunk pass, ``Acting``). Worker i seeds its env with its own seed (a new stream after
    --resume); the factories seed the envs because DistributedCollector.set_seed fails in torchrl 0.14.1."""
    if cfg.frames <= frames_done:
        return None
    level = dict(level=curriculum.level(), guide=cfg.guide, guide_render=cfg.guide_render) if curriculum else {}
    env_fns = [partial(env_fn, seed=cfg.seed + 1000 * batches + i, **level) for i in range(max(cfg.workers, 1))]
    return make_collector(cfg, env_fns, acting, total_frames=cfg.frames - frames_done)


def log_row(data, learner: Learner, cfg: PPOConfig, frames: int, batches: int, starts: dict, losses: dict,
            times: tuple[float, float, float, float]) -> dict:
    """The history's row of one batch: its episodes, the update's losses, the policy's mean log std (with
    self-imitation also the size and best return of its buffer) and timings; ``times``: (run start, collection
    start, collected, updated), in ``time.perf_counter`` seconds."""
    (start, tick, collected, updated), n, sil = times, data.numel(), learner.sil
    return {"frames": frames, "batch": batches, **batch_stats(data), **starts, **losses,
            **value_error_at_start(data, cfg.gamma), "log_std": float(action_log_std(learner.actor_critic).mean()),
            **({"sil_steps": len(sil), "sil_best_return": sil.best_return()} if sil is not None else {}),
            "collect_s": collected - tick, "update_s": updated - collected,
            "collect_fps": n / (collected - tick), "update_fps": n / (updated - collected),
            "fps": n / (updated - tick), "rss_mb": resident_mb(), "wall_s": time.perf_counter() - start}


def train(cfg: PPOConfig) -> dict:
    """Train, evaluate on seen and unseen objects, write the report; returns the paths and results."""
    from torchrl.record.loggers import CSVLogger

    start = time.perf_counter()
    out = open_run(cfg)
    ckpt_path = out / CHECKPOINT
    learner_threads = cfg.threads or torch.get_num_threads()
    torch.set_num_threads(learner_threads)
    torch.manual_seed(cfg.seed)

    # ---- env factory (picklable, for the worker processes), the learner, and where we start from
    env_fn = partial(make_env, cfg.task, split=cfg.split, **cfg.env_kwargs())
    learner = build_learner(cfg, env_fn)
    curriculum = make_curriculum(cfg)  # the start-state schedule (None: true resets only); its state lives here
    frames_done, batches, history = restore(learner, cfg, ckpt_path, curriculum) if cfg.resume else (0, 0, [])
    if learner.demos is not None and (cfg.bc_warmstart or cfg.init_from) and not cfg.resume and cfg.eval_episodes:
        learner.demos["warmstart_eval"] = warmstart_evaluation(cfg, learner.actor_critic)  # the curve's frame 0
    device = resolve_device(cfg.device, log=tqdm.write)
    acting = learner.to(device)  # collection and evaluation act on the CPU (a copy when learning on cuda)

    # ---- collection, then learning from each batch
    collector = start_collector(cfg, env_fn, acting, curriculum, frames_done, batches)
    in_process = cfg.backend == "process" and cfg.workers <= 1  # collects in this process, one action at a time
    collect_threads = 1 if in_process else learner_threads
    logger, bar = CSVLogger(exp_name="log", log_dir=str(out)), progress_bar(cfg, frames_done)
    tick = time.perf_counter()
    try:  # shut the workers down on errors too
        torch.set_num_threads(collect_threads)
        for data in (collector if collector is not None else []):  # not `or []`: RayCollector breaks bool()
            collected = time.perf_counter()
            torch.set_num_threads(learner_threads)
            data, losses = learn(data, learner, acting, cfg, batches, device)
            collector.update_policy_weights_()
            starts = curriculum.update(data) if curriculum is not None else {}  # frontiers move on this batch
            if cfg.curriculum == "reverse":
                send_level(collector, curriculum.level())
            if cfg.trim_memory:
                release_freed_memory()  # the update's freed activations back to the OS (see utils)
            updated = time.perf_counter()

            # ---- logging and checkpoints
            frames_done, batches = frames_done + data.numel(), batches + 1
            row = log_row(data, learner, cfg, frames_done, batches, starts, losses, (start, tick, collected, updated))
            history.append(row)
            logger.log_metrics({k: v for k, v in row.items() if not math.isnan(v)}, step=frames_done)
            bar.update(data.numel())
            bar.set_postfix(ret=f"{row['episode_return']:.1f}", succ=f"{row['success_rate']:.2f}", fps=f"{row['fps']:.0f}")
            if batches % cfg.checkpoint_every == 0:
                save(learner, cfg, ckpt_path, frames_done, batches, history, curriculum)
            if cfg.max_minutes is not None and time.perf_counter() - start > 60 * cfg.max_minutes:
                break
            torch.set_num_threads(collect_threads)
            tick = time.perf_counter()
    finally:
        bar.close()
        if collector is not None:
            collector.shutdown()
        torch.set_num_threads(learner_threads)
    ckpt = save(learner, cfg, ckpt_path, frames_done, batches, history, curriculum)
    result = evaluate_and_report(cfg, acting, history, start)  # ---- seen and unseen objects, curve, report
    return {"checkpoint": str(ckpt), "frames": frames_done, "history": history, "demos": learner.demos,
            "device": device.type, **result}


# ---------------------------------------------------------------- command line (through rl/train.py)
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexart_lite.cli import add_config_arguments

    parser.add_argument("--preset", default="faithful", help=f"starting point: {', '.join(PRESETS)}")
    # defaults None: the preset supplies every field not given on the command line
    add_config_arguments(parser, PPOConfig, given_only=True, default_label="faithful preset")


def config_from_args(args: argparse.Namespace) -> PPOConfig:
    """The preset named by ``--preset`` with every option given on the command line (flags, ``--set``) applied."""
    from dexart_lite.cli import config_from_args as from_args

    return from_args(PPOConfig, args, lambda **given: preset(args.preset, **given))
