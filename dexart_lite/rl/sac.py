"""Off-policy RL from demonstrations with torchrl: ``SACConfig`` and ``train(cfg)`` (``dexart-lite train --algo sac``).

    dexart-lite train --algo sac --task laptop --obs state --demo-episodes 4 --frames 300000 --out runs/sac_laptop

SAC (``torchrl.objectives.SACLoss``) in the spirit of RLPD (Ball et al., ICML 2023): the guide's demonstrations
(``--demo-episodes`` per training object, from the scripted expert, training only) sit in a replay buffer of
their own and make up ``--demo-fraction`` of every batch, the rest coming from the online buffer; the critics
are an ensemble (``--critics``) of LayerNorm MLPs; ``--utd`` gradient steps per online frame. The start-state
curriculum of ``rl/curriculum.py`` is an option, exactly as for PPO (``--curriculum reverse`` ...).

``train`` reads top to bottom: env factory -> demonstrations -> actor and critics (inputs normalised with the
demonstrations' statistics) -> SACLoss, target networks, Adam -> the collector loop (collect, store, update)
-> logging and checkpoints; then the evaluation on seen and unseen objects and ``report.md``, as for PPO.

Shared with PPO: the env (``rl/env.make_env``), the trunk (``models/actor_critic.Trunk``), the curriculum,
evaluation (``dexart-lite eval`` loads these checkpoints), the learning-curve plot and the report. One
collector process (the in-process ``Collector``): SAC alternates a short collection with many updates, and
on 2 cores the updates are the cost.

A checkpoint keeps the actor, the critics and their targets, the temperature, the optimizer, the counters,
the history, the curriculum's frontiers and (``--save-buffer``, on by default) the online replay buffer,
written beside it to ``buffer/``; the demonstrations are collected again on ``--resume`` (same seeds, same
data). Not kept: the collector's env and RNG states (a resumed run collects on new seeds).
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from dataclasses import asdict, dataclass, field, fields
from functools import partial
from pathlib import Path

import torch
from tensordict import TensorDict
from tqdm import tqdm

from dexart_lite import objects as objects_lib
from dexart_lite.models.actor_critic import POINTS_KEY, STATE_KEY
from dexart_lite.models.soft_actor_critic import make_qvalue, make_sac_actor, observation_keys, sac_trunk
from dexart_lite.registration import OBSERVATIONS, TASKS
from dexart_lite.rl import common
from dexart_lite.rl.checkpoint import load_checkpoint, network_encoder, save_checkpoint
from dexart_lite.rl.common import (CHECKPOINT, batch_stats, curriculum_config, evaluate_and_report, make_curriculum,
                                   progress_bar)
from dexart_lite.rl.curriculum import guide_demos, guide_env_kwargs, send_level
from dexart_lite.rl.env import env_dims, make_env
from dexart_lite.rl.ppo_config import PPOConfig
from dexart_lite.models.pointnet import ENCODER_SIZES
from dexart_lite.utils import (DEVICES, check_choice, optimizer_to, release_freed_memory, resident_mb, resolve_device,
                               to_cpu)

BUFFER_DIR = "buffer"
LOSS_KEYS = ("loss_actor", "loss_qvalue", "loss_alpha", "alpha", "entropy")
_PPO_HELP = {f.name: f.metadata.get("help", "") for f in fields(PPOConfig)}


def same_as_ppo(name: str, default):
    """A field that means what PPOConfig's field of the same name means (its help text)."""
    return field(default=default, metadata={"help": _PPO_HELP[name]})


@dataclass
class SACConfig:
    """One off-policy run. The defaults are SAC's usual settings (lr 3e-4, tau 0.005, batch 256, two critics)
    with RLPD's LayerNorm critics and 50 % demonstrations per batch, on the state-only observation."""

    task: str = same_as_ppo("task", "laptop")
    obs: str = field(default="state", metadata={"help": "state (the state vector plus the privileged object state, "
                     "an MLP; what fits a CPU) or cloud (point cloud + state, a PointNet in the actor and in every "
                     "critic: ~100x the update cost)"})
    encoder: str = same_as_ppo("encoder", "small")
    device: str = same_as_ppo("device", "cpu")
    frames: int = field(default=300_000, metadata={"help": "online env frames (the guide's steps and the "
                        "demonstrations are not counted)"})
    frames_per_batch: int = field(default=1000, metadata={"help": "frames collected between two rounds of updates"})
    utd: float = field(default=1.0, metadata={"help": "gradient steps per online frame (RLPD: 20 with 10 critics; "
                       "each costs ~5 ms for the state MLPs on 2 cores)"})
    batch: int = field(default=256, metadata={"help": "transitions per gradient step"})
    lr: float = field(default=3e-4, metadata={"help": "Adam learning rate of the actor, the critics and the temperature"})
    gamma: float = 0.99
    tau: float = field(default=0.005, metadata={"help": "target critics: Polyak averaging rate"})
    critics: int = field(default=2, metadata={"help": "Q-networks in the ensemble (the target is the minimum over all)"})
    layer_norm: bool = field(default=True, metadata={"help": "LayerNorm in the critics' hidden layers (RLPD)"})
    head: str = field(default="256", metadata={"help": "hidden widths of the actor's and the critics' MLPs after "
                      "the trunk (the trunk's state MLP is two more 256-unit layers: 3 hidden layers in all, one more "
                      "than RLPD's; each layer costs ~20 %% of an update on a CPU)"})
    state_hidden: int = field(default=256, metadata={"help": "width of each trunk's state MLP"})
    init_alpha: float = field(default=0.1, metadata={"help": "initial entropy temperature (learnt; target entropy "
                              "-action_dim)"})
    reward_scale: float = same_as_ppo("reward_scale", 0.01)
    buffer: int = field(default=300_000, metadata={"help": "online replay buffer capacity (transitions, in memory: "
                        "~0.5 kB each on the state observation, ~15 kB with point clouds)"})
    warmup_frames: int = field(default=5000, metadata={"help": "online frames collected before the first update"})
    demo_episodes: int = field(default=4, metadata={"help": "guide demonstrations per training object in the "
                               "demonstration buffer (rl/curriculum.guide_demos; the scripted expert, privileged, "
                               "training only). 0: none"})
    demo_noise: float = same_as_ppo("demo_noise", 0.1)
    demo_fraction: float = field(default=0.5, metadata={"help": "share of every batch drawn from the demonstrations "
                                 "(RLPD: 0.5)"})
    split: str = same_as_ppo("split", "seen")
    reward: str = same_as_ppo("reward", "dexart")
    num_points: int = same_as_ppo("num_points", 512)
    max_episode_steps: int | None = same_as_ppo("max_episode_steps", None)
    curriculum: str = same_as_ppo("curriculum", "none")
    curriculum_horizon: int = same_as_ppo("curriculum_horizon", 130)
    curriculum_demos: int = same_as_ppo("curriculum_demos", 11)
    curriculum_step: int = same_as_ppo("curriculum_step", 5)
    curriculum_successes: int = same_as_ppo("curriculum_successes", 3)
    curriculum_backoff: int = same_as_ppo("curriculum_backoff", 0)
    curriculum_true_resets: float = same_as_ppo("curriculum_true_resets", 0.1)
    curriculum_probe: float = same_as_ppo("curriculum_probe", 0.0)
    guide: str = same_as_ppo("guide", "expert")
    guide_render: bool = same_as_ppo("guide_render", False)
    seed: int = 0
    out: str = field(default="runs/sac", metadata={"help": "output folder (checkpoint, buffer, logs, report)"})
    checkpoint_every: int = same_as_ppo("checkpoint_every", 5)
    save_buffer: bool = field(default=True, metadata={"help": "write the online replay buffer with every checkpoint "
                              "(a resumed run then replays what it had)"})
    max_minutes: float | None = same_as_ppo("max_minutes", None)
    resume: bool = same_as_ppo("resume", False)
    eval_episodes: int = same_as_ppo("eval_episodes", 3)
    eval_seed: int = 100
    gif: bool = same_as_ppo("gif", False)
    threads: int = same_as_ppo("threads", 0)
    progress: bool = same_as_ppo("progress", True)
    trim_memory: bool = same_as_ppo("trim_memory", True)
    algo: str = field(default="sac", metadata={"help": "the learner (recorded in the checkpoint)"})

    def head_widths(self) -> tuple[int, ...]:
        return common.head_widths(self.head)  # same parsing and error as PPO's --head

    def env_kwargs(self) -> dict:
        return common.env_kwargs(self)  # same env keywords as PPO (hand: the 22-D joints action)

    hand = "joints"  # read by env_kwargs; not a field: SAC acts on the full hand


def validate(cfg: SACConfig) -> None:
    check_choice("task", cfg.task, TASKS)
    check_choice("observation", cfg.obs, OBSERVATIONS)
    check_choice("encoder size", cfg.encoder, ENCODER_SIZES)
    check_choice("training split", cfg.split, objects_lib.TRAINING_SPLITS)
    check_choice("device", cfg.device, DEVICES)
    if cfg.device == "cuda":
        resolve_device(cfg.device)  # no CUDA here: one line, before anything is built
    cfg.head_widths()
    for name in ("frames", "frames_per_batch", "batch", "critics", "buffer", "num_points", "checkpoint_every",
                 "state_hidden"):
        if getattr(cfg, name) < 1:
            raise ValueError(f"{name} must be >= 1, got {getattr(cfg, name)}")
    if cfg.critics < 2:
        raise ValueError(f"critics must be >= 2 (the target takes the minimum over the ensemble), got {cfg.critics}")
    if not 0.0 <= cfg.demo_fraction <= 1.0:
        raise ValueError(f"demo_fraction is a fraction in [0, 1], got {cfg.demo_fraction}")
    if cfg.demo_fraction > 0 and cfg.demo_episodes < 1:
        raise ValueError("--demo-fraction > 0 needs demonstrations: set --demo-episodes >= 1 (or --demo-fraction 0)")
    if cfg.demo_fraction == 1.0:
        raise ValueError("--demo-fraction 1 would never replay the online data: use a fraction below 1")
    if cfg.demo_episodes < 0 or cfg.warmup_frames < 0:
        raise ValueError(f"demo_episodes and warmup_frames must be >= 0, got {cfg.demo_episodes}, {cfg.warmup_frames}")
    if not (math.isfinite(cfg.utd) and cfg.utd > 0):
        raise ValueError(f"utd (updates per frame) must be > 0, got {cfg.utd}")
    if not 0.0 < cfg.tau <= 1.0 or not 0.0 < cfg.gamma <= 1.0:
        raise ValueError(f"need 0 < tau <= 1 and 0 < gamma <= 1, got {cfg.tau}, {cfg.gamma}")
    if not (math.isfinite(cfg.init_alpha) and cfg.init_alpha > 0) or not cfg.reward_scale > 0:
        raise ValueError(f"init_alpha and reward_scale must be > 0, got {cfg.init_alpha}, {cfg.reward_scale}")
    if cfg.buffer < cfg.frames_per_batch:
        raise ValueError(f"buffer ({cfg.buffer}) must hold at least one batch ({cfg.frames_per_batch} frames)")
    curriculum_config(cfg).validate()  # schedule, guide, horizon, fraction of true resets


# ---------------------------------------------------------------- replay
def transition_keys(encoder: str) -> list:
    """What a stored transition keeps (the rest of a collector batch, info and counters, is dropped)."""
    obs = observation_keys(encoder)
    return [*obs, "action", *[("next", k) for k in obs], ("next", "reward"), ("next", "terminated"), ("next", "done")]


def make_buffer(capacity: int):
    """A uniform replay buffer in memory (torchrl ``LazyTensorStorage``)."""
    from torchrl.data import LazyTensorStorage, ReplayBuffer
    from torchrl.data.replay_buffers.samplers import RandomSampler

    return ReplayBuffer(storage=LazyTensorStorage(capacity), sampler=RandomSampler())


def store(buffer, data, keys: list, reward_scale: float, demo: bool) -> None:
    """Add the transitions of ``data`` (any batch shape) to ``buffer``, rewards times ``reward_scale`` and a
    ``demo`` flag (True for the demonstrations)."""
    flat = data.reshape(-1).select(*keys).clone()
    flat["next", "reward"] = flat["next", "reward"] * reward_scale
    flat["demo"] = torch.full((flat.numel(),), demo)
    buffer.extend(flat)


def mixed_batch(online, demos, size: int, demo_fraction: float):
    """``size`` transitions: ``round(size * demo_fraction)`` from ``demos``, the rest from ``online`` (RLPD's
    symmetric sampling); ``batch["demo"]`` marks which is which."""
    n_demo = int(round(size * demo_fraction)) if demos is not None else 0
    parts = [online.sample(size - n_demo)]
    if n_demo:
        parts.append(demos.sample(n_demo))
    return torch.cat(parts)


# ---------------------------------------------------------------- the learner
def demonstrations(cfg: SACConfig) -> tuple[TensorDict | None, dict]:
    """The guide's transitions on the training objects (None without ``--demo-episodes``) and what they were."""
    if not cfg.demo_episodes:
        return None, {"frames": 0}
    data, success = guide_demos(cfg.task, cfg.split, cfg.demo_episodes, cfg.demo_noise, 10_000 + cfg.seed,
                                guide_env_kwargs(cfg.env_kwargs()), cfg.guide, transitions=True)
    return data, {"frames": len(data), "guide_success": success}


def normalization_samples(cfg: SACConfig, env_fn, demos) -> TensorDict:
    """States (and clouds) that fix the networks' input normalisation: the demonstrations, or without them
    2,000 steps of random actions."""
    if demos is not None:
        return demos
    env = env_fn(seed=cfg.seed)
    try:
        return env.rollout(2000, break_when_any_done=False)
    finally:
        env.close()


def build(cfg: SACConfig, env_fn, demos):
    """(actor, loss module with the critics and their targets, target updater, optimizer, dims)."""
    from torchrl.objectives import SACLoss, SoftUpdate

    probe = env_fn()
    num_points, state_dim, action_dim = env_dims(probe)
    action_spec = probe.action_spec
    probe.close()
    encoder = network_encoder(asdict(cfg))
    actor = make_sac_actor(state_dim, action_dim, encoder, cfg.head_widths(), cfg.state_hidden)
    qvalue = make_qvalue(state_dim, action_dim, encoder, cfg.head_widths(), cfg.state_hidden, cfg.layer_norm)
    if not cfg.resume:  # a resumed run loads the statistics with the weights
        samples = normalization_samples(cfg, env_fn, demos)
        for module in (actor, qvalue):  # before SACLoss copies the critic into its ensemble
            sac_trunk(module).set_normalization(samples[STATE_KEY], samples.get(POINTS_KEY, None))
    with torch.no_grad():  # initialise lazy shapes: one forward pass
        td = TensorDict({STATE_KEY: torch.zeros(1, state_dim)}, [1])
        if encoder != "none":
            td[POINTS_KEY] = torch.zeros(1, num_points, 3)
        qvalue(actor(td))
    loss = SACLoss(actor_network=actor, qvalue_network=qvalue, num_qvalue_nets=cfg.critics, loss_function="l2",
                   alpha_init=cfg.init_alpha, action_spec=action_spec, delay_qvalue=True)
    loss.make_value_estimator(gamma=cfg.gamma)
    updater = SoftUpdate(loss, tau=cfg.tau)
    optimizer = torch.optim.Adam([p for p in loss.parameters() if p.requires_grad], lr=cfg.lr)
    dims = {"num_points": num_points, "state_dim": state_dim, "action_dim": action_dim,
            "head": list(cfg.head_widths()), "state_hidden": cfg.state_hidden, "normalize": True}
    return actor, loss, updater, optimizer, dims


def update(loss, updater, optimizer, sample) -> dict:
    """One gradient step on actor, critics and temperature (the actor's loss reads detached critics, so one
    backward pass serves all three), then the targets' Polyak step; the loss terms as floats."""
    out = loss(sample)
    total = out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]
    optimizer.zero_grad()
    total.backward()
    optimizer.step()
    updater.step()
    return {k: float(out[k].detach()) for k in LOSS_KEYS}


# ---------------------------------------------------------------- checkpoints
def save(path: Path, cfg: SACConfig, actor, loss, optimizer, online, frames: int, batches: int, history: list,
         dims: dict, curriculum, demo_info: dict) -> Path:
    """``model`` is the actor alone (what ``dexart-lite eval`` loads); ``loss`` holds everything SAC learns."""
    if cfg.save_buffer:
        online.dumps(path.parent / BUFFER_DIR)
    return save_checkpoint(path, {
        "config": asdict(cfg), "model": to_cpu(actor.state_dict()), "loss": to_cpu(loss.state_dict()),
        "optimizer": to_cpu(optimizer.state_dict()), "frames": frames, "batches": batches, "history": history, "dims": dims,
        "curriculum": curriculum.state_dict() if curriculum is not None else None, "demos": demo_info,
        "buffer_saved": cfg.save_buffer})


def restore(path: Path, cfg: SACConfig, actor, loss, optimizer, online, curriculum) -> tuple[int, int, list]:
    state = load_checkpoint(path)
    if state["config"].get("algo") != "sac":
        raise ValueError(f"--resume: {path} is not an off-policy (--algo sac) run")
    for name in ("task", "obs", "encoder", "critics", "head", "state_hidden", "layer_norm"):
        if state["config"][name] != getattr(cfg, name):
            raise ValueError(f"--resume: {path} has {name}={state['config'][name]!r}, this run {getattr(cfg, name)!r}")
    if (state["curriculum"] is None) != (curriculum is None):
        raise ValueError(f"--resume: {path} has curriculum {state['config']['curriculum']!r}, this run "
                         f"{cfg.curriculum!r}")
    if curriculum is not None:
        curriculum.load_state_dict(state["curriculum"])
    loss.load_state_dict(state["loss"], strict=True)
    actor.load_state_dict(state["model"], strict=True)
    optimizer.load_state_dict(state["optimizer"])
    buffer_dir = path.parent / BUFFER_DIR
    if state.get("buffer_saved") and buffer_dir.is_dir():
        online.loads(buffer_dir)
    else:
        print(f"--resume: {path} kept no replay buffer: the online buffer starts empty")
    return state["frames"], state["batches"], state["history"]


# ---------------------------------------------------------------- training
def place(cfg: SACConfig, actor, loss, optimizer) -> tuple:
    """The networks, the loss and Adam's moments moved to ``cfg.device`` (a resumed run loaded them on the
    CPU); returns the device and the actor the collector and the evaluation act with (a CPU copy on cuda)."""
    device = resolve_device(cfg.device, log=tqdm.write)
    if device.type == "cpu":
        return device, actor
    acting = copy.deepcopy(actor)
    actor.to(device)
    loss.to(device)
    optimizer_to(optimizer, device)
    return device, acting


def learn(steps: int, cfg: SACConfig, loss, updater, optimizer, online, demo_buffer, device) -> dict:
    """``steps`` updates on batches mixed from the online and the demonstration buffers; the mean of each loss
    term (NaN without updates) and the demonstrations' share of the last batch."""
    sums, demo_share = dict.fromkeys(LOSS_KEYS, 0.0), math.nan
    for _ in range(steps):
        sample = mixed_batch(online, demo_buffer, cfg.batch, cfg.demo_fraction)
        sample = sample.to(device) if device.type != "cpu" else sample
        for key, value in update(loss, updater, optimizer, sample).items():
            sums[key] += value
        demo_share = float(sample["demo"].float().mean())
    return {**{k: (v / steps if steps else math.nan) for k, v in sums.items()}, "demo_share": demo_share}


def make_buffers(cfg: SACConfig, demos, keys) -> tuple:
    """The online replay buffer and, with demonstrations mixed in, a second buffer holding them (else ``None``)."""
    online = make_buffer(cfg.buffer)
    if demos is None or cfg.demo_fraction <= 0:
        return online, None
    demo_buffer = make_buffer(len(demos))
    store(demo_buffer, demos, keys, cfg.reward_scale, demo=True)
    return online, demo_buffer


def train(cfg: SACConfig) -> dict:
    """Train, evaluate on seen and unseen objects, write the report; returns the paths and results."""
    from torchrl.collectors import Collector
    from torchrl.record.loggers import CSVLogger

    validate(cfg)
    start = time.perf_counter()
    out = Path(cfg.out)
    if cfg.resume and not (out / CHECKPOINT).exists():
        raise FileNotFoundError(f"--resume: no checkpoint in {out}")
    out.mkdir(parents=True, exist_ok=True)
    threads = cfg.threads or torch.get_num_threads()
    torch.set_num_threads(threads)
    torch.manual_seed(cfg.seed)

    # ---- env factory, demonstrations, networks and loss, replay buffers, curriculum; or the checkpoint's state
    env_fn = partial(make_env, cfg.task, split=cfg.split, **cfg.env_kwargs())
    demos, demo_info = demonstrations(cfg)
    actor, loss, updater, optimizer, dims = build(cfg, env_fn, demos)
    keys = transition_keys(network_encoder(asdict(cfg)))
    online, demo_buffer = make_buffers(cfg, demos, keys)
    curriculum = make_curriculum(cfg)
    frames_done, batches, history = (restore(out / CHECKPOINT, cfg, actor, loss, optimizer, online, curriculum)
                                     if cfg.resume else (0, 0, []))
    device, acting = place(cfg, actor, loss, optimizer)
    on_device = device.type != "cpu"

    # ---- collection: one env in this process, the actor's stochastic actions
    collector = None
    if cfg.frames > frames_done:
        level = dict(level=curriculum.level(), guide=cfg.guide, guide_render=cfg.guide_render) if curriculum else {}
        collector = Collector(partial(env_fn, seed=cfg.seed + 1000 * batches, **level), acting,
                              frames_per_batch=cfg.frames_per_batch, total_frames=cfg.frames - frames_done)
    logger, bar = CSVLogger(exp_name="log", log_dir=str(out)), progress_bar(cfg, frames_done)
    tick = time.perf_counter()
    try:
        for data in (collector if collector is not None else []):  # not `or []`: RayCollector breaks bool()
            collected = time.perf_counter()
            store(online, data, keys, cfg.reward_scale, demo=False)
            starts = curriculum.update(data) if curriculum is not None else {}
            if cfg.curriculum == "reverse":
                send_level(collector, curriculum.level())
            n = data.numel()
            frames_done, batches = frames_done + n, batches + 1

            # ---- updates: utd per collected frame, once the warm-up frames are in
            steps = int(round(cfg.utd * n)) if frames_done >= cfg.warmup_frames else 0
            losses = learn(steps, cfg, loss, updater, optimizer, online, demo_buffer, device)
            if on_device:
                acting.load_state_dict(actor.state_dict())
            collector.update_policy_weights_()
            if cfg.trim_memory:
                release_freed_memory()  # the updates' freed activations back to the OS (see utils)
            updated = time.perf_counter()

            # ---- logging and checkpoints
            row = {"frames": frames_done, "batch": batches, **batch_stats(data), **starts,
                   **losses, "updates": steps, "buffer": len(online), "collect_s": collected - tick,
                   "update_s": updated - collected, "fps": n / (updated - tick), "rss_mb": resident_mb(),
                   "wall_s": time.perf_counter() - start}
            history.append(row)
            logger.log_metrics({k: v for k, v in row.items() if not math.isnan(v)}, step=frames_done)
            bar.update(n)
            bar.set_postfix(succ=f"{row['success_rate']:.2f}", q=f"{row['loss_qvalue']:.3f}", fps=f"{row['fps']:.0f}")
            if batches % cfg.checkpoint_every == 0:
                save(out / CHECKPOINT, cfg, actor, loss, optimizer, online, frames_done, batches, history, dims,
                     curriculum, demo_info)
            if cfg.max_minutes is not None and time.perf_counter() - start > 60 * cfg.max_minutes:
                break
            tick = time.perf_counter()
    finally:
        bar.close()
        if collector is not None:
            collector.shutdown()
    ckpt = save(out / CHECKPOINT, cfg, actor, loss, optimizer, online, frames_done, batches, history, dims,
                curriculum, demo_info)
    result = evaluate_and_report(cfg, acting, history, start)  # ---- seen and unseen objects, curve, report
    return {"checkpoint": str(ckpt), "frames": frames_done, "history": history, "demos": demo_info,
            "device": device.type, **result}


# ---------------------------------------------------------------- command line (through rl/train.py)
def config_from_args(args: argparse.Namespace) -> SACConfig:
    """SACConfig with every option given on the command line (flags not None, ``--set``) applied."""
    from dexart_lite.cli import config_from_args as from_args

    return from_args(SACConfig, args)


__all__ = ["SACConfig", "mixed_batch", "store", "train", "transition_keys", "validate"]
